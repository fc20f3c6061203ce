"""BVH files in and out: ``read_bvh``/``parse_bvh`` give a ``Clip``, ``write_bvh``/``format_bvh`` take one.

What is supported and decided here:

* Any hierarchy of one ROOT, JOINTs and End Sites; tabs or spaces; CRLF or LF; gzip files
  (recognised by their magic bytes, whatever the suffix). Joints keep the file's order,
  which is depth-first, so the MOTION columns follow the joints.
* Each joint may declare any subset of the six channels in any order; the tuple is kept on
  the ``Skeleton`` so writing reproduces the layout. The rotation channels fix the joint's
  Euler order (``rotations.from_euler``). A joint with fewer than three rotation channels
  is read as the missing axes being zero; writing it can only express those axes.
* Position channels REPLACE the joint's offset for that frame (the Bandai files animate
  every joint's position channels with its OFFSET, and their Hips carry the body while the
  Hips OFFSET is meaningless). The root's land in ``Clip.root_positions``; when any other
  joint has position channels, ``Clip.translations`` (T, J, 3) holds every joint's local
  translation (the offset where a joint has none), otherwise it is None. A missing axis of
  a partial set of position channels keeps the offset's value.
* fps is 1 / Frame Time, snapped to the nearest integer when within 1e-4 relative of it:
  exporters print 0.0333333 for 30 fps, which is 30.00003. Written Frame Times use 10
  significant digits, so integer rates round-trip exactly and others to ~1e-9.
* MOTION rows are checked (one frame per line, exactly the declared channel count) and
  their numbers parsed by ``_decimals``, a vectorised exact decimal parser (bit-identical
  to ``float()``), in line-aligned chunks of 256 KiB so temporaries stay in cache and the
  text is never copied.
* Every problem with a file raises ``UserError`` with one sentence naming the file, the
  line and the fix. Files over 2 GiB of text, more than 10,000 joints or more than 2e9
  declared values are refused before anything big is allocated.
"""

from __future__ import annotations

import gzip
import io
import re
import zlib
from bisect import bisect_right
from functools import lru_cache
from itertools import accumulate, chain
from pathlib import Path

import numpy as np

from . import _decimals
from . import rotations as rot
from .clip import Clip
from .errors import UserError
from .skeleton import POSITION_CHANNELS, ROTATION_CHANNELS, Skeleton

MAX_JOINTS = 10_000
MAX_VALUES = 2_000_000_000
MAX_TEXT_BYTES = 2 << 30
# The HIERARCHY is tokenised into Python objects (~100 bytes per word and per line), so a
# hostile header of 50 MB would cost gigabytes: it is bounded first, by what MAX_JOINTS
# joints can need (a joint takes ~15 words and ~6 lines; deep indentation takes bytes).
MAX_HEADER_WORDS = 40 * MAX_JOINTS
MAX_HEADER_LINES = 50 * MAX_JOINTS
MAX_HEADER_BYTES = 64 << 20
# A MOTION row holds `channels` numbers; a line far longer than that is refused before
# it is tokenised (tokenising costs ~18 bytes of temporaries per byte of text).
MAX_BYTES_PER_VALUE = 100
_WORD = re.compile(rb"\S+")
FPS_SNAP_TOLERANCE = 1e-4
_CHUNK_BYTES = 1 << 18  # MOTION is parsed in line-aligned chunks so temporaries stay in cache
_CHANNEL_NAMES = {c.lower(): c for c in POSITION_CHANNELS + ROTATION_CHANNELS}


# ----------------------------------------------------------------------------- reading files

def read_bvh(path: str | Path) -> Clip:
    """Read a .bvh or gzip-compressed .bvh(.gz) file."""
    path = Path(path)
    return _parse_bytes(_read_text_bytes(path), str(path))


def require_frames(clip: Clip, what: str) -> Clip:
    """``clip``, or one sentence when it has no frame to play, restyle or emulate (a BVH
    with ``Frames: 0`` is valid; every command that moves it needs one)."""
    if clip.num_frames < 1:
        raise UserError(f"{what} has no frames (its MOTION section is empty); export it again with its motion")
    return clip


def parse_bvh(text: str | bytes, source_name: str = "<bvh>") -> Clip:
    """Parse BVH text; ``source_name`` names it in error messages."""
    data = text.encode("utf-8") if isinstance(text, str) else text
    return _parse_bytes(data, source_name)


def _read_text_bytes(path: Path) -> bytes | bytearray:
    try:
        size = path.stat().st_size
        if size > MAX_TEXT_BYTES:
            raise UserError(f"{path} holds {size:,} bytes, more than the {MAX_TEXT_BYTES:,} bytes of BVH text stylecast reads; split it into shorter clips.")
        raw = path.read_bytes()
    except FileNotFoundError:
        raise UserError(f"{path} does not exist; check the path and the working directory.") from None
    except IsADirectoryError:
        raise UserError(f"{path} is a directory, not a BVH file; name a .bvh or .bvh.gz file inside it.") from None
    except PermissionError:
        raise UserError(f"{path} cannot be read (permission denied); fix its permissions or copy it somewhere readable.") from None
    except OSError as e:
        raise UserError(f"{path} cannot be read ({e.strerror or e}); check the file and the disk.") from None
    return _gunzip(raw, path) if raw[:2] == b"\x1f\x8b" else raw


def _gunzip(raw: bytes, path: Path) -> bytearray:
    # Streamed into one growing buffer: a gzip bomb is stopped at the size limit, and the
    # text is held once (no list of chunks joined into a second copy).
    text = bytearray()
    try:
        with gzip.GzipFile(fileobj=io.BytesIO(raw)) as f:
            while chunk := f.read(1 << 24):
                text += chunk
                if len(text) > MAX_TEXT_BYTES:
                    raise UserError(f"{path} decompresses to more than the {MAX_TEXT_BYTES:,} bytes of BVH text stylecast reads; split it into shorter clips.")
    except (OSError, EOFError, zlib.error) as e:
        raise UserError(f"{path} starts like a gzip file but cannot be decompressed ({e}); download or export it again.") from None
    return text


# ----------------------------------------------------------------------------- the header

class _Tokens:
    """Whitespace tokens of the HIERARCHY section; line numbers are worked out only when needed."""

    def __init__(self, text: str, source: str):
        per_line = [line.split() for line in text.split("\n")]
        self.flat = list(chain.from_iterable(per_line))
        self.line_ends = list(accumulate(map(len, per_line)))  # token index just past each line
        self.end_of_line = [end for end, tokens in zip(self.line_ends, per_line) for _ in tokens]
        self.source, self.i = source, 0

    def next(self) -> str | None:
        self.i += 1
        return self.flat[self.i - 1] if self.i <= len(self.flat) else None

    def line_of(self, index: int) -> int:
        return bisect_right(self.line_ends, max(min(index, len(self.flat) - 1), 0)) + 1

    @property
    def line_no(self) -> int:
        """Line of the token read last."""
        return self.line_of(self.i - 1)

    def rest_of_line(self) -> list[str]:
        end = self.end_of_line[self.i - 1]
        rest, self.i = self.flat[self.i:end], end
        return rest

    def fail(self, problem: str, line: int | None = None) -> UserError:
        return UserError(f"{self.source} line {line or self.line_no}: {problem}.")


def _parse_hierarchy(tokens: _Tokens) -> Skeleton:
    first = tokens.next()
    if first is None:
        raise tokens.fail("the file is empty; export the BVH again", 1)
    if first != "HIERARCHY":
        raise tokens.fail(f"expected HIERARCHY but found {first!r}; this is not a BVH file")
    if tokens.next() != "ROOT":
        raise tokens.fail("expected 'ROOT <name>' after HIERARCHY; add the root joint")
    names: dict[str, int] = {}  # name -> index: a dict, so the duplicate check stays O(1)
    parents, offsets, channels, end_sites = [], [], [], []
    stack = [_open_joint(tokens, -1, names, parents, offsets, channels)]  # (joint or None for an End Site, index of its '{')
    site_offset = (0.0, 0.0, 0.0)
    while stack:
        tok, (joint, opened) = tokens.next(), stack[-1]
        if tok is None:
            what = f"joint {list(names)[joint]!r}" if joint is not None else "End Site"
            raise tokens.fail(f"the hierarchy ends with the '{{' of {what} from line {tokens.line_of(opened)} still open; add the missing '}}'")
        if tok == "OFFSET":
            value = _offset(tokens)
            if joint is None:
                site_offset = value
            else:
                offsets[joint] = value
        elif tok == "CHANNELS" and joint is not None:
            channels[joint] = _channels(tokens)
        elif tok == "JOINT" and joint is not None:
            stack.append(_open_joint(tokens, joint, names, parents, offsets, channels))
        elif tok == "End" and joint is not None:
            if tokens.next() != "Site" or tokens.next() != "{":
                raise tokens.fail("expected 'End Site' followed by '{'; fix the End Site block")
            stack.append((None, tokens.i - 1))
            site_offset = (0.0, 0.0, 0.0)
        elif tok == "}":
            stack.pop()
            if joint is None:
                end_sites.append((stack[-1][0], site_offset))
        else:
            where = f"joint {list(names)[joint]!r}" if joint is not None else "an End Site"
            raise tokens.fail(f"unexpected {tok!r} inside {where}; expected OFFSET, CHANNELS, JOINT, End Site or '}}'")
    extra = tokens.next()
    if extra is not None:
        problem = ("a second ROOT; stylecast reads one skeleton per file, so split the file" if extra == "ROOT"
                   else f"{extra!r} after the ROOT's closing '}}'; a '}}' above closes too early or is extra, remove it")
        raise tokens.fail(problem)
    return Skeleton(names, parents, offsets, channels, end_sites)


def _open_joint(tokens: _Tokens, parent: int, names, parents, offsets, channels) -> tuple[int, int]:
    words = tokens.rest_of_line()
    brace_on_line = bool(words) and words[-1] == "{"
    name = " ".join(words[:-1] if brace_on_line else words)
    if not name:
        raise tokens.fail("a joint has no name; write 'JOINT <name>'")
    if name in names:
        raise tokens.fail(f"joint name {name!r} is used twice; rename one of them")
    if len(names) >= MAX_JOINTS:
        raise tokens.fail(f"more than {MAX_JOINTS} joints; this is not a skeleton stylecast can use, check the file")
    if not brace_on_line and tokens.next() != "{":
        raise tokens.fail(f"expected '{{' after joint {name!r}; add it")
    names[name] = len(names)
    parents.append(parent), offsets.append((0.0, 0.0, 0.0)), channels.append(())
    return len(names) - 1, tokens.i - 1


def _offset(tokens: _Tokens) -> tuple[float, float, float]:
    values = [tokens.next() for _ in range(3)]
    try:
        x, y, z = (float(v) for v in values)
        if all(abs(c) < float("inf") for c in (x, y, z)):  # also false for nan
            return x, y, z
    except (TypeError, ValueError):
        pass
    raise tokens.fail(f"OFFSET needs three finite numbers, got {' '.join(v for v in values if v)!r}; fix the OFFSET line")


def _channels(tokens: _Tokens) -> tuple[str, ...]:
    parsed = _channel_names(tuple(tokens.rest_of_line()))
    if isinstance(parsed, str):
        raise tokens.fail(parsed)
    return parsed


@lru_cache(maxsize=256)  # every joint of a file usually repeats the same CHANNELS line
def _channel_names(words: tuple[str, ...]) -> tuple[str, ...] | str:
    """The canonical channel names of a CHANNELS line, or what is wrong with it."""
    if not words or not words[0].isdigit():
        return "CHANNELS must start with the channel count; write 'CHANNELS <n> <names>'"
    count, listed = int(words[0]), words[1:]
    if count != len(listed):
        return f"CHANNELS declares {count} channels but names {len(listed)}; make the count match the names"
    names = tuple(_CHANNEL_NAMES.get(word.lower(), word) for word in listed)
    for word, name in zip(listed, names):
        if name not in _CHANNEL_NAMES.values():
            return f"unknown channel {word!r}; use Xposition, Yposition, Zposition, Xrotation, Yrotation or Zrotation"
    if len(set(names)) != len(names):
        return f"a channel is listed twice in {' '.join(listed)!r}; list each channel once"
    return names


# ----------------------------------------------------------------------------- MOTION header

def _parse_bytes(data: bytes | bytearray, source: str) -> Clip:
    if not data or data.isspace():  # isspace() scans without copying, unlike strip()
        raise UserError(f"{source} line 1: the file is empty; export the BVH again.")
    found = _find_motion_line(data)
    motion_at = found[0] if found else len(data)
    _check_header_size(data, motion_at, source)
    skeleton = _parse_hierarchy(_Tokens(data[:motion_at].decode("utf-8", "replace"), source))
    if found is None:
        last = data.rstrip().count(b"\n") + 1  # the last line with text (error path: the copy is fine)
        raise UserError(f"{source} line {last}: there is no MOTION section after the hierarchy; the file is cut short, export it again.")
    line_no = data.count(b"\n", 0, motion_at) + 1
    frames_text, frames_line, pos = _next_line(data, found[1], line_no)
    frames = _frames(frames_text, source, frames_line)
    time_text, line_no, pos = _next_line(data, pos, frames_line)
    fps = _fps(time_text, source, line_no)
    layout = _layout(skeleton.channels, tuple(range(len(skeleton))))
    if layout.num_channels == 0:
        raise UserError(f"{source} line {line_no}: the hierarchy declares no CHANNELS, so there is no motion to read; add CHANNELS to the joints.")
    if frames * layout.num_channels > MAX_VALUES:
        raise UserError(f"{source} line {frames_line}: {frames} frames of {layout.num_channels} channels is more than the {MAX_VALUES:.0e} values stylecast reads; split the clip.")
    values = _motion_values(data, pos, line_no + 1, frames, layout.num_channels, source)
    return _clip_from_channels(skeleton, layout, values, fps)


def _check_header_size(data, end: int, source: str) -> None:
    """Refuse a hierarchy too big for MAX_JOINTS joints before it is tokenised (hardening)."""
    problem, at = None, -1
    if end > MAX_HEADER_BYTES:
        problem, at = f"{MAX_HEADER_BYTES:,} bytes", MAX_HEADER_BYTES
    elif data.count(b"\n", 0, end) > MAX_HEADER_LINES:
        problem = f"{MAX_HEADER_LINES:,} lines"
        at = 0
        for _ in range(MAX_HEADER_LINES + 1):
            at = data.find(b"\n", at) + 1
    else:
        for count, match in enumerate(_WORD.finditer(data, 0, end)):  # one match object at a time
            if count == MAX_HEADER_WORDS:
                problem, at = f"{MAX_HEADER_WORDS:,} words", match.start()
                break
    if problem:
        line = data.count(b"\n", 0, at) + 1
        raise UserError(f"{source} line {line}: the hierarchy is longer than {problem}, more than {MAX_JOINTS:,} "
                        f"joints can need; this is not a skeleton stylecast can use, check the file.")


def _find_motion_line(data) -> tuple[int, int] | None:
    """Where the line that holds only MOTION starts and the next one starts (a joint may be called MOTION_1)."""
    at = data.find(b"MOTION")
    while at >= 0:
        start, end = data.rfind(b"\n", 0, at) + 1, data.find(b"\n", at)
        end = len(data) if end < 0 else end
        if end - start <= 4096 and data[start:end].strip() == b"MOTION":  # (no copy of a huge line)
            return start, end + 1
        # Resume after this line, not after this occurrence: a line repeating MOTION
        # would otherwise be rescanned once per occurrence (quadratic; a 1 MB file took
        # minutes). Lines are then each scanned a bounded number of times (hardening).
        at = data.find(b"MOTION", end)
    return None


def _next_line(data, pos: int, line_no: int) -> tuple[str, int, int]:
    """The next non-blank line after ``pos`` (which ends line ``line_no``): text, its number, the position after it."""
    while pos < len(data):
        stop = data.find(b"\n", pos)
        stop = len(data) if stop < 0 else stop
        line_no += 1
        text = data[pos:stop].decode("utf-8", "replace").strip()
        pos = stop + 1
        if text:
            return text, line_no, pos
    return "", line_no, len(data)


def _frames(text: str, source: str, line_no: int) -> int:
    match = re.fullmatch(r"Frames:\s*(\S+)", text)
    if not match:
        raise UserError(f"{source} line {line_no}: expected 'Frames: <count>' after MOTION but found {text[:40]!r}; add the frame count line.")
    if not match[1].isdigit():
        raise UserError(f"{source} line {line_no}: the frame count {match[1]!r} is not a whole number; write 'Frames: <count>'.")
    return int(match[1])


def _fps(text: str, source: str, line_no: int) -> float:
    match = re.fullmatch(r"Frame\s+Time:\s*(\S+)", text)
    if not match:
        raise UserError(f"{source} line {line_no}: expected 'Frame Time: <seconds>' after the Frames line but found {text[:40]!r}; add the frame time line.")
    try:
        frame_time = float(match[1])
    except ValueError:
        frame_time = float("nan")
    if not (0 < frame_time < float("inf") and 1.0 / frame_time < float("inf")):
        raise UserError(f"{source} line {line_no}: Frame Time {match[1]!r} is not a positive number of seconds; write it as 1 / fps, such as 'Frame Time: 0.0333333' for 30 fps.")
    fps = 1.0 / frame_time
    nearest = round(fps)
    return float(nearest) if nearest > 0 and abs(fps - nearest) <= FPS_SNAP_TOLERANCE * fps else fps


# ----------------------------------------------------------------------------- MOTION rows

def _motion_values(data, start: int, first_line: int, frames: int, channels: int, source: str) -> np.ndarray:
    """The (frames, channels) matrix of the MOTION rows, checking the row structure as it goes."""
    n = len(data)
    # No row of `channels` numbers is shorter than 2 * channels bytes, so a declared count
    # the text cannot hold never gets its memory: the loop below reports the truncation.
    out = np.empty(min(frames * channels, (n - start + 1) // 2 + channels))
    buf, words = np.frombuffer(data, np.uint8), _decimals.byte_windows(data)
    rows, filled, line, last_row_line, pos = 0, 0, first_line, first_line - 1, start
    max_row = channels * MAX_BYTES_PER_VALUE + 4096
    while pos < n:
        stop = 0
        if pos + _CHUNK_BYTES < n:
            # The chunk ends at the first newline after _CHUNK_BYTES, searched only as far
            # as a row can reach: a longer line is refused before it costs any memory.
            stop = data.find(b"\n", pos + _CHUNK_BYTES, pos + _CHUNK_BYTES + max_row) + 1
            if not stop and pos + _CHUNK_BYTES + max_row < n:
                long_line = line + data.count(b"\n", pos, pos + _CHUNK_BYTES)
                raise UserError(f"{source} line {long_line}: the line is longer than {max_row:,} bytes, far more than "
                                f"a frame of {channels} values needs; every frame must be one line of exactly "
                                f"{channels} numbers.")
        stop = stop or n  # find() gave -1: no newline left
        chunk = buf[pos:stop]
        line_ends = np.flatnonzero(chunk == 10)
        starts, ends = _decimals.token_bounds(chunk)
        bounds = line_ends if chunk[-1] == 10 else np.append(line_ends, len(chunk))
        per_line = np.diff(np.searchsorted(starts, bounds), prepend=0)
        row_lines = np.flatnonzero(per_line)
        counts = per_line[row_lines]
        row_lines += line
        _check_rows(counts, row_lines, rows, frames, channels, source, at_end=stop == n)
        starts, ends = starts + pos, ends + pos
        values, ok = _decimals.parse_fast(buf, words, starts, ends)
        if not ok.all() and (bad := _decimals.parse_rest(data, starts, ends, values, ok)) is not None:
            bad_line = line + int(np.searchsorted(line_ends + pos, starts[bad]))
            raise _not_a_number(bytes(data[starts[bad]:ends[bad]]), bad_line, source)
        out[filled:filled + len(values)] = values
        filled, rows, pos, line = filled + len(values), rows + len(counts), stop, line + len(line_ends)
        last_row_line = row_lines[-1] if len(row_lines) else last_row_line
    if rows < frames:
        raise UserError(f"{source} line {last_row_line}: the file ends after {rows} of the {frames} frames that 'Frames:' declares; it is truncated, export it again or set 'Frames: {rows}'.")
    return out[:filled].reshape(frames, channels)


def _not_a_number(token: bytes, line: int, source: str) -> UserError:
    text = token.decode("utf-8", "replace")[:40]
    try:
        float(text)
        kind = "not a finite number"
    except ValueError:
        kind = "not a number"
    return UserError(f"{source} line {line}: {text!r} is {kind}; replace it with a decimal value such as 0.0.")


def _check_rows(counts, row_lines, rows_before, frames, channels, source, at_end) -> None:
    bad = np.flatnonzero(counts != channels)
    extra = frames - rows_before  # index of the first row beyond the declared count
    if extra < len(counts) and (not len(bad) or bad[0] >= extra):
        raise UserError(f"{source} line {row_lines[extra]}: there are more frame rows than the {frames} that 'Frames:' declares; set 'Frames:' to the number of rows or delete the extra rows.")
    if not len(bad):
        return
    k = bad[0]
    if at_end and k == len(counts) - 1 and counts[k] < channels:
        raise UserError(f"{source} line {row_lines[k]}: the file ends in the middle of frame {rows_before + k + 1} of {frames} ({counts[k]} of {channels} values); it is truncated, export it again.")
    raise UserError(f"{source} line {row_lines[k]}: frame {rows_before + k + 1} has {counts[k]} values but the CHANNELS declare {channels}; every frame must be one line of exactly {channels} numbers.")


# ----------------------------------------------------------------------------- channels <-> clip

class _Layout:
    """Where each joint's channels sit in a MOTION row, for joints written in ``joint_order``."""

    def __init__(self, channels: tuple[tuple[str, ...], ...], joint_order: tuple[int, ...]):
        rot_cols, rot_joints, rot_slots, pos_cols, pos_joints, pos_axes = ([] for _ in range(6))
        self.orders: dict[str, list[int]] = {}
        for j in joint_order:
            declared = "".join(c[0] for c in channels[j] if c in ROTATION_CHANNELS)
            # Axes a joint does not declare are appended with angle zero: the same rotation.
            order = declared + "".join(a for a in "XYZ" if a not in declared)
            self.orders.setdefault(order, []).append(j)
            for name in channels[j]:
                column = len(rot_cols) + len(pos_cols)
                if name in ROTATION_CHANNELS:
                    rot_cols.append(column), rot_joints.append(j), rot_slots.append(order.index(name[0]))
                else:
                    pos_cols.append(column), pos_joints.append(j), pos_axes.append("XYZ".index(name[0]))
        self.num_channels = len(rot_cols) + len(pos_cols)
        self.rot = tuple(np.array(a, np.intp) for a in (rot_cols, rot_joints, rot_slots))
        self.pos = tuple(np.array(a, np.intp) for a in (pos_cols, pos_joints, pos_axes))


@lru_cache(maxsize=64)  # a data set shares one layout; building it costs more than parsing a short clip
def _layout(channels: tuple[tuple[str, ...], ...], joint_order: tuple[int, ...]) -> _Layout:
    return _Layout(channels, joint_order)


def _clip_from_channels(skeleton: Skeleton, layout: _Layout, values: np.ndarray, fps: float) -> Clip:
    T, J = len(values), len(skeleton)
    angles = np.zeros((T, J, 3))
    cols, joints, slots = layout.rot
    angles[:, joints, slots] = values[:, cols]
    quats = np.empty((T, J, 4))
    for order, js in layout.orders.items():  # one vectorised conversion per Euler order
        quats[:, js] = rot.from_euler(angles[:, js], order)
    translations = np.array(np.broadcast_to(skeleton.offsets, (T, J, 3)))
    cols, joints, axes = layout.pos
    translations[:, joints, axes] = values[:, cols]
    animated = any(skeleton.has_position_channels(j) for j in range(1, J))
    return Clip(skeleton, quats, translations[:, 0].copy(), fps, translations if animated else None)


# ----------------------------------------------------------------------------- writing

def write_bvh(clip: Clip, path: str | Path, precision: int = 6) -> None:
    """Write ``clip`` as BVH text with ``precision`` decimals; gzip it when the name ends in .gz."""
    path = Path(path)
    data = format_bvh(clip, precision).encode("utf-8")
    if path.name.endswith(".gz"):
        data = gzip.compress(data, compresslevel=6, mtime=0)
    try:
        path.write_bytes(data)
    except OSError as e:
        raise UserError(f"{path} cannot be written ({e.strerror or e}); check that its folder exists and is writable.") from None


def format_bvh(clip: Clip, precision: int = 6) -> str:
    """BVH text of ``clip``: joints depth-first (the file order BVH requires), channel values with ``precision`` decimals."""
    skeleton = clip.skeleton
    order = _depth_first(skeleton)
    layout = _layout(skeleton.channels, tuple(order))
    values = _channels_from_clip(clip, layout)
    if not np.isfinite(values).all():
        raise ValueError("the clip holds NaN or infinite values, which BVH cannot store")
    lines = ["HIERARCHY"]
    _format_hierarchy(skeleton, lines)
    lines += ["MOTION", f"Frames: {clip.num_frames}", f"Frame Time: {1.0 / clip.fps:.10g}"]
    header = "\n".join(lines) + "\n"
    return header + _format_rows(values, precision)


def _children(skeleton: Skeleton) -> list[list[int]]:
    children = [[] for _ in skeleton.names]
    for j, p in enumerate(skeleton.parents[1:], start=1):
        children[p].append(j)
    return children


def _depth_first(skeleton: Skeleton) -> list[int]:
    children, order, stack = _children(skeleton), [], [0]
    while stack:
        j = stack.pop()
        order.append(j)
        stack.extend(reversed(children[j]))
    return order


def _format_hierarchy(skeleton: Skeleton, lines: list[str]) -> None:
    # An explicit stack, not recursion: a chain of thousands of joints must not hit the limit.
    children = _children(skeleton)
    sites: dict[int, list] = {}
    for joint, offset in skeleton.end_sites:
        sites.setdefault(joint, []).append(offset)
    stack: list = [("joint", 0, 0)]
    while stack:
        kind, item, depth = stack.pop()
        tab = "\t" * depth
        if kind == "close":
            lines.append(f"{tab}}}")
        elif kind == "site":
            lines += [f"{tab}End Site", f"{tab}{{", f"{tab}\tOFFSET {_numbers(item)}", f"{tab}}}"]
        else:
            channels = skeleton.channels[item]
            keyword = "ROOT" if skeleton.parents[item] < 0 else "JOINT"
            lines += [f"{tab}{keyword} {skeleton.names[item]}", f"{tab}{{",
                      f"{tab}\tOFFSET {_numbers(skeleton.offsets[item])}",
                      f"{tab}\tCHANNELS {len(channels)}{''.join(' ' + c for c in channels)}"]
            todo = ([("joint", c, depth + 1) for c in children[item]]
                    + [("site", o, depth + 1) for o in sites.get(item, [])] + [("close", None, depth)])
            stack.extend(reversed(todo))


def _numbers(values) -> str:
    return " ".join(repr(float(v)) for v in values)  # shortest text that reads back exactly


def _channels_from_clip(clip: Clip, layout: _Layout) -> np.ndarray:
    T, J = clip.num_frames, len(clip.skeleton)
    angles = np.zeros((T, J, 3))
    for order, js in layout.orders.items():
        angles[:, js] = rot.to_euler(clip.rotations[:, js], order)
    values = np.empty((T, layout.num_channels))
    cols, joints, slots = layout.rot
    values[:, cols] = angles[:, joints, slots]
    cols, joints, axes = layout.pos
    if len(cols):
        values[:, cols] = clip.local_translations()[:, joints, axes]
    return values


def _format_rows(values: np.ndarray, precision: int, block: int = 1024) -> str:
    # One %-format per block of rows: the per-number work happens inside str.__mod__.
    row = " ".join([f"%.{int(precision)}f"] * values.shape[1])
    parts = []
    for start in range(0, len(values), block):
        chunk = values[start:start + block]
        parts.append("\n".join([row] * len(chunk)) % tuple(chunk.ravel().tolist()) + "\n")
    return "".join(parts)
