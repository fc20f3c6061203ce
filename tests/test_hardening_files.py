"""Untrusted files (issue 7, part 5): checkpoints are never unpickled, bad checkpoints and
absurd BVH files are refused (or read) without a traceback and without exhausting memory.

Already covered in tests/test_models.py: missing, truncated, flipped-byte, wrong-shape,
wrong-metadata and foreign checkpoints; in tests/test_bvh.py: 10,001 joints, 10^12
declared frames, over-long files (with the limit monkeypatched), gzip bombs, random
corruption. Added here: a scan of the package source for every unpickling API; a pickle
payload disguised as a checkpoint (refused, and never executed); header and metadata
*types* an attacker controls; and BVH files of absurd sizes read in a subprocess whose
peak memory is measured (a 50 MB single line stands in for the "1 GB line": the test
bounds the memory per byte, which is what decides whether 1 GB would fit).
"""

from __future__ import annotations

import ast
import json
import struct
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from stylecast.motion.errors import UserError

REPO = Path(__file__).resolve().parents[1]
PACKAGE_DIRS = ("motion", "drivers", "models", "daemon", "viewer", "stylecast")


# ------------------------------------------------------------------ nothing unpickles

UNSAFE_CALLS = {
    ("torch", "load"), ("torch.jit", "load"), ("pickle", "load"), ("pickle", "loads"), ("pickle", "Unpickler"),
    ("cPickle", "load"), ("cPickle", "loads"), ("dill", "load"), ("dill", "loads"), ("cloudpickle", "load"),
    ("cloudpickle", "loads"), ("joblib", "load"), ("marshal", "load"), ("marshal", "loads"), ("shelve", "open"),
    ("pandas", "read_pickle"), ("pd", "read_pickle"), ("yaml", "load"), ("yaml", "unsafe_load"),
}
UNSAFE_MODULES = {"pickle", "cPickle", "_pickle", "dill", "cloudpickle", "shelve", "marshal", "joblib"}


def _dotted(node) -> str:
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return f"{_dotted(node.value)}.{node.attr}"
    return ""


def unsafe_uses(source: str, filename: str) -> list[str]:
    found = []
    for node in ast.walk(ast.parse(source, filename)):
        if isinstance(node, ast.Import):
            found += [f"{filename}:{node.lineno} import {a.name}" for a in node.names
                      if a.name.split(".")[0] in UNSAFE_MODULES]
        elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] in UNSAFE_MODULES:
            found.append(f"{filename}:{node.lineno} from {node.module} import ...")
        elif isinstance(node, ast.Call):
            name = _dotted(node.func)
            owner, _, attr = name.rpartition(".")
            if (owner, attr) in UNSAFE_CALLS or (owner.endswith("torch") and attr == "load"):
                found.append(f"{filename}:{node.lineno} {name}(...)")
            if attr == "load" and owner in ("np", "numpy"):
                for kw in node.keywords:
                    if kw.arg == "allow_pickle" and not (isinstance(kw.value, ast.Constant) and kw.value.value is False):
                        found.append(f"{filename}:{node.lineno} {name}(..., allow_pickle={ast.unparse(kw.value)})")
            if name in ("eval", "exec"):
                found.append(f"{filename}:{node.lineno} {name}(...)")
    return found


def test_the_scanner_finds_what_it_looks_for():
    bad = textwrap.dedent("""
        import pickle
        from dill import loads
        import torch, numpy as np
        torch.load("x.pt")
        np.load("a.npy", allow_pickle=True)
        np.load("a.npy", allow_pickle=flag)
        eval("1")
    """)
    assert len(unsafe_uses(bad, "bad.py")) == 6
    ok = 'import numpy as np\nnp.load("a.npz", allow_pickle=False)\nmodel.eval()\n'
    assert unsafe_uses(ok, "ok.py") == []


def test_no_package_source_can_unpickle_or_eval():
    files = [p for d in PACKAGE_DIRS for p in sorted((REPO / d).rglob("*.py"))]
    assert len(files) > 30
    found = [hit for p in files for hit in unsafe_uses(p.read_text(encoding="utf-8"), str(p.relative_to(REPO)))]
    assert not found, found


# ------------------------------------------------------------------ hostile checkpoints

def _load(path):
    from stylecast.models.restyler import Restyler

    return Restyler.load(str(path))


def _one_sentence(message: str) -> bool:
    return "\n" not in message and "Traceback" not in message


def test_a_pickle_disguised_as_a_checkpoint_is_refused_and_never_runs(tmp_path):
    import pickle

    marker = tmp_path / "pwned"

    class Payload:
        def __reduce__(self):  # unpickling this would create the marker file
            return (open, (str(marker), "w"))

    for name, data in (("plain.safetensors", pickle.dumps(Payload(), protocol=4)),
                       ("zipped.safetensors", _torch_save_bytes(Payload()))):
        path = tmp_path / name
        path.write_bytes(data)
        with pytest.raises(UserError, match="corrupt or truncated") as e:
            _load(path)
        assert _one_sentence(str(e.value)) and not marker.exists()


def _torch_save_bytes(obj) -> bytes:
    """What ``torch.save`` writes (a zip holding data.pkl)."""
    import io

    torch = pytest.importorskip("torch")
    buf = io.BytesIO()
    torch.save({"weights": obj}, buf)
    return buf.getvalue()


def test_a_safetensors_header_claiming_a_huge_size_is_refused_at_once(tmp_path):
    for claimed, body in ((1 << 40, b"{}"), (100, b'{"__metadata__": {"stylecast": "' + b"x" * 10 + b'"}')):
        path = tmp_path / "huge.safetensors"
        path.write_bytes(struct.pack("<Q", claimed) + body)
        with pytest.raises(UserError, match="corrupt or truncated"):
            _load(path)
    # a tensor whose declared shape needs far more bytes than the file holds
    header = json.dumps({"w": {"dtype": "F32", "shape": [1 << 20, 1 << 20], "data_offsets": [0, 16]}}).encode()
    path.write_bytes(struct.pack("<Q", len(header)) + header + bytes(16))
    with pytest.raises(UserError, match="corrupt or truncated"):
        _load(path)


@pytest.fixture(scope="module")
def tiny_checkpoint(tmp_path_factory) -> Path:
    pytest.importorskip("torch")
    from stylecast.models import checkpoint as ckpt
    from stylecast.models.train import Trainer, model_metadata

    from .test_models import _tiny_cfg, synthetic_words

    out = tmp_path_factory.mktemp("model") / "tiny.safetensors"
    cfg = _tiny_cfg()
    tr = Trainer(cfg, synthetic_words(4, 5), synthetic_words(4, 6), device="cpu")
    ckpt.save_checkpoint(out, tr.model_tensors(generators_only=True), model_metadata(cfg, tr.rep))
    return out


def _with_metadata(src: Path, dst: Path, **changes) -> Path:
    from stylecast.models import checkpoint as ckpt

    tensors, meta = ckpt.read_checkpoint(src)
    meta.update(changes)
    ckpt.save_checkpoint(dst, tensors, meta)  # a valid file (digest and all) with hostile metadata
    return dst


HOSTILE_METADATA = {
    "word_length_text": {"word_length": "sixty"},
    "fps_text": {"fps": "fast"},
    "fps_nan": {"fps": float("nan")},
    "bones_number": {"bones": 22},
    "bones_of_numbers": {"bones": list(range(22))},
    "styles_list": {"styles": ["a", "b"]},
    "styles_text": {"styles": "ab"},
    "network_text": {"network": "big"},
    "network_list": {"network": [1, 2, 3]},
    "network_huge": {"network": {"g_hidden": 1 << 30}},
    "representation_text": {"representation": "euler"},
    "representation_list": {"representation": [1]},
    "format_version_text": {"format_version": "1"},
    "retarget_version_text": {"retarget_version": "one"},
    "reference_wrong": {"representation": {"name": "euler", "reference": "xyz"}},
}


@pytest.mark.parametrize("case", sorted(HOSTILE_METADATA))
def test_hostile_metadata_types_are_refused_with_one_sentence(tiny_checkpoint, tmp_path, case):
    path = _with_metadata(tiny_checkpoint, tmp_path / f"{case}.safetensors", **HOSTILE_METADATA[case])
    with pytest.raises(UserError) as e:
        _load(path)
    assert _one_sentence(str(e.value)) and str(path) in str(e.value)


# ------------------------------------------------------------------ absurd BVH files

SMALL_HEADER = ("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 6 Xposition Yposition Zposition Zrotation "
                "Xrotation Yrotation\n  End Site\n  {\n    OFFSET 0 10 0\n  }\n}\n")
MB = 1 << 20


def _write_absurd_files(folder: Path, size: int) -> dict[str, Path]:
    """Files of about ``size`` bytes, written in blocks (never a whole copy in memory)."""
    files = {}

    def write(name, head, block, tail, repeat_to=size):
        path = folder / name
        with open(path, "wb") as f:
            f.write(head)
            written = 0
            while written < repeat_to:
                f.write(block)
                written += len(block)
            f.write(tail)
        files[name] = path

    motion = b"MOTION\nFrames: 1\nFrame Time: 0.0333333\n"
    write("one_line_of_numbers.bvh", SMALL_HEADER.encode() + motion, b"0 " * 65536, b"\n")
    write("one_line_one_token.bvh", SMALL_HEADER.encode() + motion, b"7" * 131072, b"\n")
    write("millions_of_joints.bvh", b"HIERARCHY\nROOT r\n{\nOFFSET 0 0 0\n",
          b"JOINT j\n{\nOFFSET 0 0 0\n}\n" * 4096, b"}\nMOTION\nFrames: 0\nFrame Time: 1\n")
    write("hierarchy_one_line.bvh", b"HIERARCHY\nROOT r\n{\nOFFSET 0 0 0 ", b"0 " * 65536,
          b"\n}\nMOTION\nFrames: 0\nFrame Time: 1\n")
    write("hierarchy_blank_lines.bvh", b"HIERARCHY\n", b"\n" * 131072, b"ROOT r\n{\nOFFSET 0 0 0\n}\nMOTION\n")
    write("motion_word_repeated.bvh", b"HIERARCHY\nROOT r\n{\nOFFSET 0 0 0 ", b"MOTION " * 8192,
          b"\n}\nMOTION\nFrames: 0\nFrame Time: 1\n")
    write("no_motion_section.bvh", b"HIERARCHY\nROOT r\n{\nOFFSET 0 0 0\n", b"OFFSET 0 0 0\n" * 8192, b"")
    small = SMALL_HEADER.encode()
    (folder / "frames_1e8_declared.bvh").write_bytes(small + b"MOTION\nFrames: 100000000\nFrame Time: 0.01\n"
                                                     + b"0 0 0 0 0 0\n" * 10)
    files["frames_1e8_declared.bvh"] = folder / "frames_1e8_declared.bvh"
    (folder / "frames_1e12_declared.bvh").write_bytes(small + b"MOTION\nFrames: 1000000000000\nFrame Time: 0.01\n"
                                                      + b"0 0 0 0 0 0\n")
    files["frames_1e12_declared.bvh"] = folder / "frames_1e12_declared.bvh"
    # A legitimately long clip, for scale: 300,000 frames of 6 channels (~4 MB).
    write("long_but_valid.bvh", small + b"MOTION\nFrames: 300000\nFrame Time: 0.01\n",
          b"0 1 2 3 4 5\n" * 10000, b"", repeat_to=12 * 300000 - 1)
    return files


PROBE = textwrap.dedent("""
    import json, sys, time
    from stylecast.motion.bvh import read_bvh
    from stylecast.motion.errors import UserError

    def status(key):
        for line in open("/proc/self/status"):
            if line.startswith(key):
                return int(line.split()[1]) / 1024

    out = {}
    for path in sys.argv[1:]:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")  # reset the peak (VmHWM) to the current RSS
        base = status("VmRSS")
        t0 = time.perf_counter()
        try:
            clip = read_bvh(path)
            result = f"read: {clip.num_frames} frames of {len(clip.skeleton)} joints"
        except UserError as e:
            result = "refused: " + str(e)
        out[path] = {"growth_mb": status("VmHWM") - base, "seconds": time.perf_counter() - t0, "result": result}
    print(json.dumps(out))
""")


@pytest.mark.skipif(not Path("/proc/self/clear_refs").exists(), reason="needs Linux /proc to measure peak memory")
def test_absurd_bvh_files_are_refused_or_read_within_bounded_memory(tmp_path):
    size = 50 * MB
    files = _write_absurd_files(tmp_path, size)
    r = subprocess.run([sys.executable, "-c", PROBE, *map(str, files.values())], capture_output=True, text=True,
                       timeout=600, cwd=REPO)
    assert r.returncode == 0, r.stderr[-2000:]
    report = json.loads(r.stdout)
    print()
    for name, path in files.items():
        m = report[str(path)]
        print(f"{name:<28} {path.stat().st_size / MB:7.1f} MB  peak growth {m['growth_mb']:7.1f} MB  "
              f"{m['seconds']:5.1f} s  {m['result'][:110]}")
    for name, path in files.items():
        m = report[str(path)]
        on_disk = path.stat().st_size / MB
        assert m["result"].startswith("refused: " + str(path) + " line ") or name == "long_but_valid.bvh", m
        assert "\n" not in m["result"]
        # Bounded: the text itself (read whole, as read_bvh does) plus a small constant,
        # never a multiple of it; the bar is < 500 MB for these files.
        assert m["growth_mb"] < min(500, 1.5 * on_disk + 120), (name, m)
        # Linear time: a few seconds per 50 MB even on a loaded machine (the quadratic
        # MOTION search this caught took over 10 minutes for a 1 MB file).
        assert m["seconds"] < 120, (name, m)
    assert report[str(files["long_but_valid.bvh"])]["result"] == "read: 300000 frames of 1 joints"
