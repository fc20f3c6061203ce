"""``--record out.bvh``: humanoid motion written to BVH while it plays, and its repair.

Frames are appended and flushed as they come (by a writer thread, so a slow disk never
holds up the 60 Hz output clock); the header's ``Frames:`` count is written as a
fixed-width field and fixed up in place on close. A ``kill -9`` leaves a file whose
frame lines are all there (flushed to the OS every frame, so at most the frames still in
the writer's queue are lost, a few milliseconds' worth) but whose count says 0 and whose
last line may be cut: ``repair_bvh`` (``stylecast repair FILE.bvh``) drops a cut last
line and rewrites the count.

Channels: the root has ``Xposition Yposition Zposition Zrotation Xrotation Yrotation``,
every other joint ``Zrotation Xrotation Yrotation`` (the Bandai order), degrees, cm.
The humanoid's rest pose is its T-pose, so a rotation of zero is the T-pose.
"""

from __future__ import annotations

import os
import queue
import re
import threading
from pathlib import Path

import numpy as np

from stylecast.motion import rotations as rot
from stylecast.motion.clock import OUTPUT_FPS
from stylecast.motion.errors import UserError
from stylecast.motion.skeleton import Skeleton

COUNT_WIDTH = 10  # "Frames:" field width: room for 10^10 frames, rewritten in place
EULER_ORDER = "ZXY"
_ROOT_CHANNELS = "Xposition Yposition Zposition Zrotation Xrotation Yrotation"
_JOINT_CHANNELS = "Zrotation Xrotation Yrotation"


def bvh_header(skeleton: Skeleton, fps: float) -> tuple[str, str, list[int]]:
    """(text before the frame count, text after it, joint order of the channel values)."""
    lines: list[str] = ["HIERARCHY"]
    order: list[int] = []
    children = {j: skeleton.children(j) for j in range(len(skeleton))}
    end_sites = dict(skeleton.end_sites)

    def joint(j: int, depth: int) -> None:
        pad = "\t" * depth
        order.append(j)
        kind = "ROOT" if skeleton.parents[j] < 0 else "JOINT"
        ox, oy, oz = skeleton.offsets[j]
        lines.append(f"{pad}{kind} {skeleton.names[j]}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}\tOFFSET {ox:.6f} {oy:.6f} {oz:.6f}")
        ch = _ROOT_CHANNELS if kind == "ROOT" else _JOINT_CHANNELS
        lines.append(f"{pad}\tCHANNELS {len(ch.split())} {ch}")
        for c in children[j]:
            joint(c, depth + 1)
        if not children[j]:
            ex, ey, ez = end_sites.get(j, (0.0, 0.0, 0.0))
            lines.extend([f"{pad}\tEnd Site", f"{pad}\t{{", f"{pad}\t\tOFFSET {ex:.6f} {ey:.6f} {ez:.6f}",
                          f"{pad}\t}}"])
        lines.append(f"{pad}}}")

    joint(0, 0)
    lines += ["MOTION", "Frames: "]
    return "\n".join(lines), f"\nFrame Time: {1.0 / fps:.7f}\n", order


def format_frame(root_position: np.ndarray, rotations: np.ndarray, order: list[int]) -> str:
    """One MOTION line: root position, then each joint's Z X Y angles in file order."""
    angles = rot.to_euler(np.asarray(rotations)[order], EULER_ORDER).reshape(-1)
    values = np.concatenate([np.asarray(root_position, np.float64).reshape(3), angles])
    return " ".join(f"{v:.6f}" for v in values) + "\n"


class BvhRecorder:
    """Appends humanoid frames to a BVH file from a writer thread."""

    def __init__(self, path: str | Path, skeleton: Skeleton, fps: float = OUTPUT_FPS):
        self.path = Path(path)
        self.frames = 0
        try:
            self._file = open(self.path, "wb")
        except OSError as exc:
            raise UserError(f"cannot record to {self.path}: {exc.strerror}; choose a writable path") from None
        before, after, self._order = bvh_header(skeleton, fps)
        head = before.encode()
        self._count_offset = len(head)
        self._file.write(head + b"0".rjust(COUNT_WIDTH) + after.encode())
        self._file.flush()
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self._closed = False
        self.error: str | None = None
        self._thread = threading.Thread(target=self._run, name=f"bvh-recorder:{self.path.name}", daemon=True)
        self._thread.start()

    def append(self, root_position: np.ndarray, rotations: np.ndarray) -> None:
        if not self._closed:
            self._queue.put((np.array(root_position, np.float64), np.array(rotations, np.float64)))

    def _run(self) -> None:
        while True:
            item = self._queue.get()
            if item is None:
                return
            if self.error is not None:
                continue
            try:
                self._file.write(format_frame(*item, self._order).encode())
                self._file.flush()  # into the OS: survives a kill -9 of this process
                self.frames += 1
            except (OSError, ValueError) as exc:
                self.error = str(exc)  # disk full etc.: stop recording, keep the show going

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._queue.put(None)
        self._thread.join()
        try:
            self._file.seek(self._count_offset)
            self._file.write(str(self.frames).rjust(COUNT_WIDTH).encode())
            self._file.flush()
            os.fsync(self._file.fileno())
        except OSError as exc:
            self.error = str(exc)
        finally:
            self._file.close()


_FRAMES_RE = re.compile(rb"^(\s*Frames:)([ \t]*)(\d*)([ \t]*)$")


def repair_bvh(path: str | Path) -> tuple[int, int]:
    """Fix the frame count of a BVH file cut short (e.g. by kill -9 while recording).

    Drops an incomplete last frame line and rewrites ``Frames:``. Returns (frames kept,
    bytes dropped). Reads line by line, so a huge file does not need to fit in memory.
    """
    path = Path(path)
    try:
        f = open(path, "r+b")
    except OSError as exc:
        raise UserError(f"cannot open {path}: {exc.strerror}") from None
    with f:
        channels, count_line, count_pos, data_start = 0, b"", -1, -1
        pos = 0
        for line in iter(f.readline, b""):
            stripped = line.strip()
            if stripped.startswith(b"CHANNELS"):
                parts = stripped.split()
                channels += int(parts[1]) if len(parts) > 1 and parts[1].isdigit() else 0
            elif _FRAMES_RE.match(line.rstrip(b"\r\n")):
                count_line, count_pos = line, pos
            elif stripped.startswith(b"Frame Time:") and count_pos >= 0:
                data_start = pos + len(line)
                break
            pos += len(line)
        if channels == 0 or data_start < 0:
            raise UserError(f"{path} is not a BVH file with a MOTION section; nothing to repair")
        frames, good_end = 0, data_start
        f.seek(data_start)
        pos = data_start
        for line in iter(f.readline, b""):
            pos += len(line)
            if not line.endswith(b"\n"):
                break  # the writer was killed mid-line
            values = line.split()
            if not values:
                good_end = pos
                continue
            if len(values) != channels or not _all_numbers(values):
                break
            frames += 1
            good_end = pos
        total = f.seek(0, os.SEEK_END)
        f.truncate(good_end)
        m = _FRAMES_RE.match(count_line.rstrip(b"\r\n"))
        ending = count_line[len(count_line.rstrip(b"\r\n")):]
        field_width = len(count_line.rstrip(b"\r\n")) - len(m.group(1))
        new = str(frames).encode()
        if len(new) + 1 <= field_width:
            f.seek(count_pos)
            f.write(m.group(1) + b" " + new.rjust(field_width - 1) + ending)
        else:
            _rewrite_count(f, count_pos, len(count_line), m.group(1) + b" " + new + ending)
        return frames, total - good_end


def _all_numbers(values: list[bytes]) -> bool:
    try:
        for v in values:
            float(v)
    except ValueError:
        return False
    return True


def _rewrite_count(f, count_pos: int, old_len: int, new_line: bytes) -> None:
    """The count does not fit in place: shift the rest of the file (chunked)."""
    f.seek(count_pos + old_len)
    rest_path = Path(f.name).with_suffix(".repair.tmp")
    with open(rest_path, "w+b") as tmp:
        while chunk := f.read(1 << 20):
            tmp.write(chunk)
        f.seek(count_pos)
        f.write(new_line)
        tmp.seek(0)
        while chunk := tmp.read(1 << 20):
            f.write(chunk)
        f.truncate()
    rest_path.unlink()
