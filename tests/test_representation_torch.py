"""The torch representation path (issue 12) against the numpy reference, on real clips."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from stylecast.models import representation as R
from stylecast.models import representation_torch as RT
from stylecast.models.checkpoint import CHECKPOINT_DIR
from stylecast.models.device import Determinism, pick_device
from stylecast.models.networks import CycleGAN, NetworkConfig
from stylecast.models.restyler import Restyler
from stylecast.motion import rotations as rot
from stylecast.motion.errors import UserError

TOLERANCE_DEG = 1e-5  # the bar for "the torch path equals the numpy path"
CLIP_PATTERNS = ("*_walk_normal_*.bvh.gz", "*_run_exhausted_*.bvh.gz", "*_raise-up-both-hands_active_*.bvh.gz")
SHIPPED = sorted(p.stem for p in CHECKPOINT_DIR.glob("*.safetensors"))


@pytest.fixture(scope="module")
def real_words(bandai_root):
    """Words cut at hop 20 from three real Bandai clips of different actions and styles,
    each word in one hemisphere over time (as the cutter delivers them)."""
    from stylecast.models.data import cut_words, decode_file

    data = bandai_root / "dataset-2" / "data"
    words = []
    for pattern in CLIP_PATTERNS:
        found = sorted(data.glob(pattern))
        if not found:
            pytest.skip(f"no Bandai clip matches {pattern} in {data}")
        rotations, _ = decode_file(found[0])
        words.append(cut_words(rotations.astype(np.float64), hop=20))
    w = np.concatenate(words)
    return rot.canonical_hemisphere(w, axis=1)


def max_angle(a: np.ndarray, b: np.ndarray) -> float:
    return float(rot.angle_between(a, b).max())


def random_quats(n: int, seed: int = 0) -> np.ndarray:
    q = np.random.default_rng(seed).normal(size=(n, 22, 4))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


@pytest.mark.parametrize("name", list(R.REPRESENTATIONS))
@pytest.mark.parametrize("centred", [False, True])
def test_encode_and_decode_equal_the_numpy_reference(name, centred):
    q = random_quats(200)
    # Gimbal lock of the XZY middle angle (+-90 degrees about Z) is where the branches differ.
    q[:10, 0] = rot.from_euler(np.array([[30.0, 90.0, 0.0], [0.0, -90.0, 45.0]] * 5), "XZY")
    ref = random_quats(1, seed=1)[0] if centred else None
    rep = R.get_representation(name, ref)
    trep = RT.TorchRepresentation(rep)
    f_np = rep.encode(q)
    f_t = trep.encode(torch.from_numpy(q)).numpy()
    assert f_t.dtype == np.float32
    assert np.abs(f_t - f_np).max() <= 2e-7  # one float32 rounding at most
    assert max_angle(trep.decode(torch.from_numpy(f_np)).numpy(), rep.decode(f_np)) < TOLERANCE_DEG


def test_heading_removal_equals_the_numpy_reference():
    w = rot.canonical_hemisphere(random_quats(120).reshape(2, 60, 22, 4), axis=1)
    flat_np, yaw_np = R.remove_heading(w)
    flat_t, yaw_t = RT.remove_heading(torch.from_numpy(w))
    assert np.allclose(yaw_t.numpy(), yaw_np, atol=1e-12)
    assert max_angle(flat_t.numpy(), flat_np) < TOLERANCE_DEG
    back = RT.restore_heading(flat_t, yaw_t).numpy()
    assert max_angle(back, w) < TOLERANCE_DEG


def test_continuity_in_time_and_the_usable_check_equal_the_numpy_ones():
    q = random_quats(3 * 60).reshape(3, 60, 22, 4)
    q *= np.where(np.random.default_rng(1).random((3, 60, 22, 1)) < 0.5, -1.0, 1.0)
    assert np.min(np.sum(q[:, 1:] * q[:, :-1], axis=-1)) < 0  # the known-bad input: not continuous
    out = RT.continuous_in_time(torch.from_numpy(q)).numpy()
    assert np.array_equal(out, rot.canonical_hemisphere(q, axis=1))  # bit for bit
    assert np.min(np.sum(out[:, 1:] * out[:, :-1], axis=-1)) >= 0 and np.array_equal(np.abs(out), np.abs(q))
    q[0, 7, 3] = 0.0  # a zero-length quaternion
    q[2, 59, 21, 2] = np.inf
    expected = [False, True, False]
    assert rot.usable_words(q).tolist() == expected == RT.usable_words(torch.from_numpy(q)).tolist()


@pytest.mark.parametrize("model", SHIPPED)
@pytest.mark.parametrize("direction", ["a2b", "b2a"])
def test_shipped_euler_models_restyle_real_clips_as_the_numpy_path_does(real_words, model, direction):
    restyler = Restyler.load(model, direction)
    if hasattr(restyler, "with_mix"):  # its default style (normal) is the input as performed
        restyler = restyler.with_style("elderly:0.7,normal:0.3")
    assert restyler.rep.name == "euler"
    got = restyler.restyle_words(real_words)
    want = restyler.restyle_words_numpy(real_words)
    assert got.shape == want.shape and got.dtype == np.float64
    assert max_angle(got, want) < TOLERANCE_DEG
    assert np.all(np.sum(got * real_words, axis=-1) >= 0)  # the hemisphere fix
    assert max_angle(got, real_words) > 1.0  # the model did restyle (a test that can fail)


def random_6d_restyler(device="cpu") -> Restyler:
    """A 6D model with a non-zero head (an untrained one is the identity) and a reference."""
    torch.manual_seed(0)
    rep = R.get_representation("6d", random_quats(1, seed=2)[0] * 0.1 + np.array([0, 0, 0, 1.0]))
    rep.reference = rep.reference / np.linalg.norm(rep.reference, axis=-1, keepdims=True)
    model = CycleGAN(NetworkConfig(channels=6), rep.combine)
    with torch.no_grad():
        for g in (model.G_a2b, model.G_b2a):
            g.head.weight.normal_(0.0, 0.02)
    return Restyler(model.to(device), rep, {"styles": {"a": "x", "b": "y"}})


def test_6d_model_restyles_real_clips_as_the_numpy_path_does(real_words):
    restyler = random_6d_restyler()
    got = restyler.restyle_words(real_words)
    want = restyler.restyle_words_numpy(real_words)
    assert max_angle(got, want) < TOLERANCE_DEG
    assert max_angle(got, real_words) > 1.0


def test_a_tensor_stays_a_tensor_and_empty_batches_pass():
    restyler = Restyler.load(SHIPPED[0])
    w = rot.identity((3, 60, 22))
    out = restyler.restyle_words(torch.from_numpy(w))
    assert isinstance(out, torch.Tensor) and out.dtype == torch.float64 and out.shape == (3, 60, 22, 4)
    assert restyler.restyle_words(np.zeros((0, 60, 22, 4))).shape == (0, 60, 22, 4)
    with pytest.raises(ValueError, match="shape"):
        restyler.restyle_words(np.zeros((2, 59, 22, 4)))


@pytest.mark.parametrize("bad", ["gpu", "cuda:x", "tpu:0", "cpu:0:1"])
def test_an_unknown_device_is_one_sentence(bad):
    with pytest.raises(UserError, match="is not a device; use auto, cpu, cuda or cuda:N"):
        pick_device(bad)


def test_cpu_and_auto_devices():
    assert pick_device("cpu").type == "cpu"
    assert pick_device("auto").type == ("cuda" if torch.cuda.is_available() else "cpu")


@pytest.mark.skipif(torch.cuda.is_available(), reason="this machine has CUDA")
def test_cuda_without_cuda_is_one_sentence():
    with pytest.raises(UserError, match="no CUDA device"):
        pick_device("cuda")
    with pytest.raises(UserError, match="no CUDA device"):
        Restyler.load(SHIPPED[0], device="cuda:0")


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device on this machine")
def test_cuda_restyle_words_matches_the_cpu(real_words):
    cpu = Restyler.load(SHIPPED[0])
    cuda = Restyler.load(SHIPPED[0], device="cuda")
    assert cuda.device.type == "cuda"
    # Convolutions on the GPU may use TF32 and other reduction orders: close, not equal.
    assert max_angle(cuda.restyle_words(real_words), cpu.restyle_words(real_words)) < 0.1
    on_device = cuda.restyle_words(torch.from_numpy(real_words).cuda())
    assert on_device.device.type == "cuda"


def test_determinism_reports_an_op_once_and_passes_other_warnings(recwarn):
    lines = []
    d = Determinism(torch.device("cpu"), log=lines.append)
    import warnings

    for _ in range(3):
        with d.watch():
            warnings.warn("upsample_linear1d_backward_out_cuda does not have a deterministic implementation, "
                          "but you set 'torch.use_deterministic_algorithms(True, warn_only=True)'.")
            warnings.warn("something else", RuntimeWarning)
    assert len(lines) == 1 and "upsample_linear1d_backward_out_cuda" in lines[0]
    assert sum("something else" in str(w.message) for w in recwarn) >= 1


def test_serve_config_refuses_a_bad_device_and_loads_models_on_the_chosen_one():
    from stylecast.daemon.config import build_config
    from stylecast.daemon.restylers import load_restyler

    with pytest.raises(UserError, match="not a device"):
        build_config({}, {"device": "gpu"})
    assert build_config({}, {"device": "CPU"}).device == "cpu"
    assert load_restyler(SHIPPED[0], "cpu").device.type == "cpu"
