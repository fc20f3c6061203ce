"""``restyle_words`` runs as one traced graph (``models/pipeline.py``): the eager
pipeline's exact bits, in any batch size, with no Python between its operations (so the
GIL is released once per call, not once per operation)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from stylecast.models import pipeline
from stylecast.models.checkpoint import CHECKPOINT_DIR
from stylecast.models.restyler import Restyler
from stylecast.models.styles import STYLES
from stylecast.motion import rotations as rot

SHIPPED = sorted(p.stem for p in CHECKPOINT_DIR.glob("*.safetensors"))
EAGER_CODE = {"representation_torch.py", "networks.py", "multistyle.py", "conditioning.py", "graph.py"}  # models/


def random_words(n: int, seed: int = 0) -> np.ndarray:
    q = np.random.default_rng(seed).normal(size=(n, 60, 22, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    # A bone at gimbal lock of the representation's XZY middle angle: its own branch, which
    # a trace would have frozen had it been a Python `if`.
    q[0, :, 3] = rot.from_euler(np.array([[30.0, 90.0, 0.0]] * 60), "XZY")
    return q


def load(name: str) -> Restyler:
    return Restyler.load(name)


def conditioning_args(restyler: Restyler, n: int) -> tuple:
    """A per-word mix for a multi-style model (the daemon's case), nothing for a pair."""
    if restyler.direction:
        return ()
    return (np.random.default_rng(n).dirichlet(np.ones(len(STYLES)), size=n),)


@pytest.mark.parametrize("name", SHIPPED)
def test_the_traced_call_gives_the_eager_pipelines_bits_in_any_batch(name):
    restyler = load(name)
    for n in (7, 1, 16):  # traced on the first, run on the others
        words = random_words(n, seed=n)
        args = conditioning_args(restyler, n)
        assert np.array_equal(restyler.restyle_words(words, *args), restyler.restyle_words_eager(words, *args))


def python_calls_during(call) -> list[str]:
    """The functions of the model's eager code that Python ran during ``call()``."""
    seen = []

    def profile(frame, event, _arg):
        if event == "call" and Path(frame.f_code.co_filename).name in EAGER_CODE:
            seen.append(frame.f_code.co_name)

    sys.setprofile(profile)
    try:
        call()
    finally:
        sys.setprofile(None)
    return seen


@pytest.mark.parametrize("name", ["normal2exhausted", "multistyle"])
def test_a_call_runs_no_python_between_its_operations(name):
    restyler = load(name)
    words = random_words(8)
    args = conditioning_args(restyler, 8)
    restyler.restyle_words(words, *args)  # traced here
    assert python_calls_during(lambda: restyler.restyle_words(words, *args)) == []
    # The known-bad case: the eager pipeline runs Python between its operations, each
    # time taking the GIL back from whatever else the process is doing.
    assert len(python_calls_during(lambda: restyler.restyle_words_eager(words, *args))) > 20


def test_restylers_sharing_a_generator_share_its_graph():
    """A live style change must not trace again (a 50-90 ms stall on the model's thread)."""
    restyler = load("multistyle")
    words = random_words(3)
    restyler.restyle_words(words)
    graph = pipeline.traced(restyler.model)
    restyler.with_style("elderly:0.5,youthful:0.5").restyle_words(words)
    restyler.for_target("active").restyle_words(words)
    assert graph is not None and pipeline.traced(restyler.model) is graph


@pytest.mark.parametrize("name", ["normal2exhausted", "multistyle"])
def test_the_daemons_call_is_the_restyle_of_the_words_made_continuous_then_made_continuous(name):
    """``restyle_stream_words`` (the model thread's one traced call) gives, bit for bit, what
    the worker computed in numpy around ``restyle_words``; a word with a NaN is unusable."""
    restyler = load(name)
    for n in (5, 1, 12):
        words = random_words(n, seed=n)
        # Half the quaternions of the cutter's words may come in the other hemisphere.
        words *= np.where(np.random.default_rng(n).random((n, 60, 22, 1)) < 0.5, -1.0, 1.0)
        args = conditioning_args(restyler, n)
        out, ok = restyler.restyle_stream_words(words, *args)
        expected = rot.canonical_hemisphere(restyler.restyle_words(rot.canonical_hemisphere(words, axis=1), *args),
                                            axis=1)
        assert np.array_equal(out, expected) and ok.dtype == bool and ok.all()
    # The check is the graph's: a NaN in, a NaN out, that word alone unusable.
    words[3, 10, 5, 0] = np.nan
    assert restyler.restyle_stream_words(words, *args)[1].tolist() == [k != 3 for k in range(12)]


def test_the_daemons_call_runs_no_python_between_its_operations():
    restyler = load("normal2exhausted")
    words = random_words(8)
    restyler.restyle_stream_words(words)  # traced here
    assert python_calls_during(lambda: restyler.restyle_stream_words(words)) == []
