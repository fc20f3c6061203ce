"""Tracker poses -> humanoid pose frames: the solver's public face.

Space and units are those of ``motion.rotations`` (right-handed, Y up, facing +Z, cm,
quaternions x, y, z, w). Output rotations are local rotations of the canonical humanoid
(``HUMANOID_BONES``), relative to the calibrated skeleton's T-pose frames; the root
position is the Hips joint's world position (as in ``Retarget.to_humanoid``).

Modules, each depending only on those listed before it:

* ``solver_math``: vector and quaternion algebra written on components, which run as
  Python floats (one frame) or numpy arrays (many frames), and the (..., 3) array helpers.
* ``solver_body``: bone and role indices, the four limbs, forward kinematics helpers.
* ``solver_calibration``: ``calibrate_known_pose``, ``calibrate_tpose`` -> ``Calibration``
  (tracker straps, proportions, neutral posture, hinge axes, default poles).
* ``solver_hold``: hold of lost trackers and blend back.
* ``solver_ik``: tracker -> bone poses, and the analytic IK.
* this module: ``TrackerSolver`` composes them; ``SolvedTrackerSource`` is the daemon's
  ``serial://`` source.

The pipeline of one frame (``TrackerSolver.solve``, or ``solve_batch`` for many at once):

1. **Tracker -> bone** (``solver_ik.BonePoses``). Each tracker is rigidly strapped to a
   bone; calibration measured the strap, so a tracker pose gives its bone's world
   rotation and joint position directly.
2. **Hold and blend** (``solver_hold``). A lost tracker's bone keeps its last pose
   relative to the hips (the waist itself is placed from the thigh trackers, else follows
   the headset's translation, else freezes); when the tracker comes back the output moves
   from the held pose to the live one over ``blend_time`` seconds (smoothstep), so
   neither loss nor return ever jumps.
3. **IK** (``solver_ik``): spine from head and waist, two-bone limbs with the elbow /
   knee trackers as pole targets, hands and feet from their trackers; local rotations
   with each bone's quaternion sign kept continuous in time.

Throughput (bench/bench_solver.py): ``solve`` and ``solve_live`` run the IK on Python
floats, frame by frame (one frame's arrays are so small that numpy's per-call overhead,
not arithmetic, set the cost: 1.5 ms a frame before); ``solve_batch`` runs the same IK
code on numpy columns. All three give the same output.
"""

from __future__ import annotations

import numpy as np

from stylecast.motion.clip import Clip, PoseFrame
from stylecast.motion.clock import OUTPUT_FPS
from stylecast.motion.errors import UserError
from stylecast.motion.skeleton import Skeleton

from stylecast.drivers.trackers.solver_body import DEFAULT_BLEND_TIME, N_ROLES, R, _as_arrays
from stylecast.drivers.trackers.solver_calibration import Calibration, calibrate_known_pose, calibrate_tpose  # noqa: F401 (public API)
from stylecast.drivers.trackers.solver_hold import _HoldBlend
from stylecast.drivers.trackers.solver_ik import BonePoses, IKTables, solve_ik
from stylecast.drivers.trackers.solver_math import _align, _cross, _swing, _two_bone, _unit  # noqa: F401 (tests/test_solver.py checks them)
from stylecast.drivers.sources import Source
from stylecast.drivers.trackers.trackers import TrackerPoses


class TrackerSolver:
    """Solves tracker frames into humanoid pose frames for one performer.

    ``solve(poses)`` is the live path (stateful: hold/blend across calls);
    ``solve_batch(...)`` solves a whole recording at once with the same results.
    """

    def __init__(self, calibration: Calibration, performer: str = "", blend_time: float = DEFAULT_BLEND_TIME):
        self.cal = calibration
        self.performer = performer
        self.blend_time = float(blend_time)
        self._hold = _HoldBlend(calibration, self.blend_time)
        self._bone_poses = BonePoses(calibration)
        self._tables = IKTables(calibration)

    @property
    def skeleton(self) -> Skeleton:
        return self.cal.skeleton

    def reset(self) -> None:
        self._hold.reset()

    def solve(self, poses: TrackerPoses) -> PoseFrame:
        """One live frame (stateful: a lost tracker is held across calls)."""
        t = float(poses.timestamp)
        root, local = self._solve(self._hold, np.array((t,)), np.asarray(poses.positions, float)[None],
                                  np.asarray(poses.orientations, float)[None], np.asarray(poses.valid, bool)[None])
        return PoseFrame(self.performer, t, root[0], local[0])

    def solve_live(self, frames: list[TrackerPoses]) -> list[PoseFrame]:
        """Consecutive live frames at once (what one poll of a source delivered): the same
        result as ``solve`` on each in turn."""
        if not frames:
            return []
        ts, P, Q, V = _as_arrays(frames)
        root, local = self._solve(self._hold, ts, P, Q, V)
        return [PoseFrame(self.performer, float(t), root[i], local[i]) for i, t in enumerate(ts)]

    def solve_batch(self, timestamps, positions, orientations, valid=None) -> tuple[np.ndarray, np.ndarray]:
        """(T,) s, (T, 10, 3) cm, (T, 10, 4), (T, 10) bool -> root (T, 3), local rotations
        (T, 22, 4). Starts from a clean state and leaves the live state untouched."""
        ts = np.asarray(timestamps, float)
        V = np.ones((len(ts), N_ROLES), bool) if valid is None else np.asarray(valid, bool)
        return self._solve(_HoldBlend(self.cal, self.blend_time), ts, np.asarray(positions, float),
                           np.asarray(orientations, float), V)

    def _solve(self, hold: _HoldBlend, ts, P, Q, V):
        bp, bq = self._bone_poses(P, Q)
        bp, bq, live = hold.run(ts, bp, bq, V)
        local = solve_ik(self._tables, bp, bq, live, hold.last_local)
        hold.last_local = local[-1].copy()
        return bp[:, R.WAIST].copy(), local

    def solve_frames(self, frames: list[TrackerPoses]) -> Clip:
        """A recording of tracker frames -> a humanoid Clip (frame rate from the timestamps)."""
        ts, P, Q, V = _as_arrays(frames)
        root, local = self.solve_batch(ts, P, Q, V)
        fps = (len(ts) - 1) / (ts[-1] - ts[0]) if len(ts) > 1 and ts[-1] > ts[0] else OUTPUT_FPS
        return Clip(self.skeleton, local, root, fps)


class SolvedTrackerSource(Source):
    """A daemon source (``drivers.sources.Source``) that solves tracker samples
    into humanoid pose frames: ``serial:///dev/ttyUSB0?baud=921600&points=10&calibrate=tpose``,
    or the trackers of a ``vmc://`` source.

    The first ``calibrate`` seconds of tracker frames are the T-pose calibration (the
    performer stands in a T-pose when the source starts); frames are solved from then on.
    Tracker frames are grouped by device timestamp (``FrameAssembler``); a frame is
    complete when the next one starts or when no sample has come for ``flush_after``
    seconds. Solved frames keep the trackers' device time and rate (the source
    contract): the daemon's session maps them onto its clock and resamples them to 60 Hz.
    Never raises from ``poll``.
    """

    def __init__(self, trackers, performer: str, points: int = 10, calibrate_seconds: float = 1.0,
                 blend_time: float = DEFAULT_BLEND_TIME, calibration: Calibration | None = None,
                 flush_after: float = 0.02):
        from stylecast.drivers.trackers.trackers import FrameAssembler, roles_for_points

        self.trackers = trackers
        self.performer = performer
        self.roles = roles_for_points(points)
        self.calibrate_seconds = float(calibrate_seconds)
        self.blend_time = blend_time
        self.flush_after = flush_after
        self.assembler = FrameAssembler()
        self.solver = None if calibration is None else TrackerSolver(calibration, performer, blend_time)
        self.skeleton = None if calibration is None else calibration.skeleton
        self._calibration_frames: list[TrackerPoses] = []
        self._last_arrival = -np.inf
        self.frames_solved = 0
        self.solve_errors = 0
        self.calibration_failures = 0
        self.last_problem = ""

    def start(self, now: float) -> None:
        self._last_arrival = now

    def poll(self, now: float) -> list[PoseFrame]:
        try:
            samples = self.trackers.poll()
        except Exception as exc:  # a tracker source must not take the daemon down
            self.last_problem = str(exc)
            samples = []
        frames = self.assembler.feed(samples)
        if samples:
            self._last_arrival = now
        elif now - self._last_arrival > self.flush_after:
            last = self.assembler.flush()
            if last is not None:
                frames.append(last)
        live = []
        for f in frames:
            if self.solver is None:
                self._calibrate(f)
                continue
            live.append(f)
        try:
            solved = self.solver.solve_live(live) if live else []
        except Exception as exc:  # a bug must not take the daemon down: count it, say it once
            self.solve_errors += 1
            if self.solve_errors == 1:
                import logging

                logging.getLogger("stylecast.drivers.trackers.solver").exception("%s: solver failed", self.performer)
            self.last_problem = f"solver failed: {exc}"
            solved = []
        self.frames_solved += len(solved)
        return solved

    def _calibrate(self, frame: TrackerPoses) -> None:
        import logging

        self._calibration_frames.append(frame)
        first = self._calibration_frames[0].timestamp
        if frame.timestamp - first < self.calibrate_seconds:
            return
        try:
            cal = calibrate_tpose(self._calibration_frames, self.roles)
        except UserError as exc:
            self.calibration_failures += 1
            self.last_problem = str(exc)
            logging.getLogger("stylecast.drivers.trackers.solver").warning("%s: calibration failed (%s); trying again",
                                                                 self.performer, exc)
            self._calibration_frames = []
            return
        self.solver = TrackerSolver(cal, self.performer, self.blend_time)
        self.skeleton = cal.skeleton
        self._calibration_frames = []

    def calibrate(self) -> None:
        """Calibrate again on the next ``calibrate_seconds`` of frames (the performer
        stands in a T-pose): ``/stylecast/calibrate``. Until then nothing is solved and
        the daemon holds the last pose; the skeleton changes when calibration ends."""
        self.solver = None
        self._calibration_frames = []

    @property
    def finished(self) -> bool:
        return False

    @property
    def calibrated(self) -> bool:
        return self.solver is not None

    def counters(self) -> dict:
        out = {"frames_solved": self.frames_solved, "solve_errors": self.solve_errors, "calibrated": self.calibrated,
               "calibration_failures": self.calibration_failures, "late_samples": self.assembler.late_samples}
        decoder = getattr(self.trackers, "decoder", None)
        if decoder is not None:
            out.update(packets=decoder.frames, bad_frames=dict(decoder.bad_frames),
                       garbage_bytes=decoder.garbage_bytes)
        stats = getattr(self.trackers, "stats", None)
        if stats is not None and hasattr(stats, "disconnects"):
            out.update(disconnects=stats.disconnects, reconnects=stats.reconnects,
                       open_failures=stats.open_failures)
        return out

    def close(self) -> None:
        close = getattr(self.trackers, "close", None)
        if close is not None:
            close()


# The options every tracker source takes (serial:// and vmc:// with trackers), one spec.
TRACKER_OPTIONS = {"points": (int, 10), "calibrate": (str, "tpose"), "blend": (float, DEFAULT_BLEND_TIME)}
TPOSE_SECONDS = 1.0  # calibrate=tpose: the first second of frames, standing in a T-pose


def calibration_seconds(url, raw: str) -> float:
    """``calibrate=tpose`` (one second of T-pose) or ``calibrate=SECONDS`` of T-pose."""
    if raw.strip().lower() == "tpose":
        return TPOSE_SECONDS
    try:
        seconds = float(raw)
    except ValueError:
        seconds = float("nan")
    if not 0.1 <= seconds <= 60:
        raise UserError(f"{url.text}: calibrate={raw} must be tpose or a number of seconds between 0.1 and 60")
    return seconds


def solved_source(url, trackers, performer: str, opts: dict) -> "SolvedTrackerSource":
    if not 0.0 <= opts["blend"] <= 5:
        raise UserError(f"{url.text}: blend={opts['blend']} must be between 0 and 5 seconds")
    return SolvedTrackerSource(trackers, performer, opts["points"], calibration_seconds(url, opts["calibrate"]),
                               opts["blend"])
