"""``restyle_words`` as one TorchScript call: quaternion words in, restyled words out.

Why a traced graph and not eager torch: the Global Interpreter Lock. Eager torch
releases the GIL around each of the ~150 small operations of a restyle (heading,
representation, generator layers, hemisphere) and must win it back after each one. The
daemon calls the model from a worker thread while its output loop runs Python for every
performer, and a thread waiting for the GIL may wait ``sys.getswitchinterval()`` each
time. Measured here: 8 words that take 4.5 ms alone took from 14 to 2,050 ms beside a
thread spinning in Python, depending on how the threads fell on the cores
(``bench/bench_models.py``, "beside a busy thread"; traced: 8-15 ms); in the daemon
at 32 performers (virtual clock) a call's wall time was 1.9x its own CPU time, 1.4x
traced; at 64 performers over two processes, 8 s runs, the eager call let 96 and 1,048
frames come late, the traced one none (``bench/bench_daemon.py capacity-workers``). A
traced graph runs in torch's C++ interpreter, which releases the GIL once per call.

The graph is traced from the eager modules on the first batch (``WordPipeline``, or
``StreamWordPipeline`` for the daemon's model thread; sizes stay symbolic, so any batch
size runs it) and kept per generator module and pipeline, so every
restyler sharing a generator (directions, style mixes) shares its graph. It runs with
TorchScript's optimising passes off, so the graph computes exactly the eager operations
and gives the same bits (tests/test_pipeline.py). With the previous convolution form the
passes split its ``addmm`` into a product and a sum, which rounded differently; today's
layers (``networks.RowConv1d``) keep their bits either way, and the passes gave no speed
(8 and 64 words, measured), so they stay off rather than be trusted.
"""

from __future__ import annotations

import threading
import warnings
import weakref

import torch
from torch import nn

from . import representation_torch as RT
from .networks import from_channels, to_channels


class WordPipeline(nn.Module):
    """Words (B, T, J, 4) float64 and the generator's conditioning tensors -> restyled
    words: heading removed, encoded, generated, decoded, heading restored, each
    quaternion in the input's hemisphere (q and -q are one rotation, and the blender
    interpolates between input and output)."""

    def __init__(self, generator: nn.Module, trep: RT.TorchRepresentation):
        super().__init__()
        self.generator = generator
        self.trep = trep  # plain attribute: its reference rotations are constants of the graph

    def forward(self, words: torch.Tensor, *conditioning: torch.Tensor) -> torch.Tensor:
        flat, yaw = RT.remove_heading(words)
        features = self.trep.encode(flat)
        y = from_channels(self.generator(to_channels(features.contiguous()), *conditioning), words.shape[2])
        return RT.same_hemisphere(RT.restore_heading(self.trep.decode(y), yaw), words)


class StreamWordPipeline(WordPipeline):
    """What the daemon's model thread runs on a batch: words in any hemisphere -> (the
    restyled words, each continuous in time; (B,) bool, each word usable: finite, no
    zero-length quaternion). ``WordPipeline`` on the words made continuous in time, as
    the seam blender wants them, with the check and the output's hemisphere pass inside
    the graph: done around the call in numpy, each of their dozen operations on a batch
    released the GIL and had to win it back from the output loop. Beside a thread busy in
    Python (1 ms switch interval), a job of 8 words took 22.4 ms that way against 8.0 in
    this graph, 64 words 70.0 against 33.7 ms (alone: 4.7-4.9 and 34 ms either way; Intel
    Xeon VM, 2 vCPUs; ``bench/bench_models.py``, "the model thread's job")."""

    def forward(self, words: torch.Tensor, *conditioning: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        out = super().forward(RT.continuous_in_time(words), *conditioning)
        return RT.continuous_in_time(out), RT.usable_words(out)


class ReadingPipeline(nn.Module):
    """Words (B, T, J, 4) float64 -> each word's style probabilities (B, S), read by a
    style reader's classifier (``style_reader``) from the features the generator sees:
    heading removed, encoded, poses and velocities (``classifier.word_inputs``)."""

    def __init__(self, classifier: nn.Module, trep: RT.TorchRepresentation):
        super().__init__()
        self.classifier = classifier
        self.trep = trep

    def forward(self, words: torch.Tensor) -> torch.Tensor:
        from .classifier import word_inputs

        flat, _ = RT.remove_heading(words)
        return torch.softmax(self.classifier(word_inputs(self.trep.encode(flat))), dim=1)


# generator (or classifier) module -> {pipeline class: its graph}
_traced: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_tracing = threading.Lock()  # one trace per graph, even when two threads ask at once


def restyle(generator: nn.Module, trep: RT.TorchRepresentation, words: torch.Tensor,
            conditioning: tuple = ()) -> torch.Tensor:
    """``WordPipeline(generator, trep)(words, *conditioning)`` as one traced call."""
    return _run(WordPipeline, generator, trep, words, conditioning)


def restyle_for_stream(generator: nn.Module, trep: RT.TorchRepresentation, words: torch.Tensor,
                       conditioning: tuple = ()) -> tuple[torch.Tensor, torch.Tensor]:
    """``StreamWordPipeline(generator, trep)(words, *conditioning)`` as one traced call."""
    return _run(StreamWordPipeline, generator, trep, words, conditioning)


def read_styles(classifier: nn.Module, trep: RT.TorchRepresentation, words: torch.Tensor) -> torch.Tensor:
    """``ReadingPipeline(classifier, trep)(words)`` as one traced call: the reading, beside
    the model's own call in the daemon's model thread, must not give the GIL back to the
    output loop after each of its operations either (eager, a job of 8 words took 371 ms
    against 14 beside a thread busy in Python; ``bench/bench_models.py --model multistyle``)."""
    return _run(ReadingPipeline, classifier, trep, words, ())


def traced(generator: nn.Module, kind: type = WordPipeline):
    """The graph of ``kind`` traced for ``generator``, or None before its first call."""
    return _traced.get(generator, {}).get(kind)


def _run(kind, generator, trep, words, conditioning):
    graph = traced(generator, kind)
    if graph is None:
        graph = _trace(kind, generator, trep, words, conditioning)
    with torch.no_grad(), torch.jit.optimized_execution(False):
        return graph(words, *conditioning)


def restyle_eager(generator: nn.Module, trep: RT.TorchRepresentation, words: torch.Tensor,
                  conditioning: tuple = ()) -> torch.Tensor:
    """The same operations run one by one, not traced: the reference the graph is held to
    (tests/test_pipeline.py) and the benchmarks' baseline (the previous release's call)."""
    with torch.no_grad():
        return WordPipeline(generator, trep)(words, *conditioning)


def _trace(kind, generator, trep, words, conditioning):
    with _tracing:
        graph = traced(generator, kind)
        if graph is None:
            with torch.no_grad(), warnings.catch_warnings():
                # The graph keeps the reference rotations and the fixed matrices as
                # constants, which is what they are; the tracer warns about each.
                warnings.simplefilter("ignore", torch.jit.TracerWarning)
                # torch marks TorchScript deprecated in favour of torch.compile and
                # torch.export; neither gives this: compile fuses operations (other
                # rounding) and needs a C++ compiler at start-up, an exported program runs
                # op by op from Python. torch is pinned (constraints.txt), so it stays.
                warnings.simplefilter("ignore", DeprecationWarning)
                graph = torch.jit.trace(kind(generator, trep), (words, *conditioning), check_trace=False)
            _traced.setdefault(generator, {})[kind] = graph
    return graph
