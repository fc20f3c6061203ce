"""A VIVE-style tracker set played from a recording: ``stylecast emulate``.

A BVH clip is read, retargeted to the canonical humanoid and run through forward
kinematics; each tracker is a rigid body strapped to its bone (``trackers.NOMINAL_MOUNTS``:
the headset in front of the eyes, controllers in the palms, the waist tracker on the small
of the back, elbow and knee trackers just above the joint, foot trackers on the instep),
optionally with strap jitter, Gaussian position noise, rotation noise and dropouts (bursts
of lost tracking, as occlusion produces). 10 points: HMD, two controllers, waist, two
elbows, two knees, two feet; 6 points: head, hands, waist, feet.

Output goes to a serial device (the binary framing of ``serial_trackers``) or to a VMC
receiver (/VMC/Ext/Hmd/Pos, /Con/Pos, /Tra/Pos via ``vmc_out.encode_trackers``), paced by
an injected clock (``now()``, ``sleep(dt)``) so tests run faster than real time.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from stylecast.motion import rotations as rot
from stylecast.motion.clip import Clip, forward_kinematics
from stylecast.motion.clock import RealClock
from stylecast.motion.errors import UserError
from stylecast.motion.humanoid import HUMANOID_BONES

from stylecast.drivers.trackers.trackers import (ALL_ROLES, TrackerPoses, TrackerRole, TrackerSample, TrackerStatus, nominal_mount,
                       roles_for_points)

N_ROLES = len(ALL_ROLES)


@dataclass
class TrackerRecording:
    """Tracker poses over time, indexed by ``TrackerRole`` (absent roles never valid)."""

    timestamps: np.ndarray  # (T,) seconds
    positions: np.ndarray  # (T, 10, 3) cm
    orientations: np.ndarray  # (T, 10, 4)
    valid: np.ndarray  # (T, 10) bool
    roles: tuple[TrackerRole, ...]

    def __len__(self) -> int:
        return len(self.timestamps)

    def arrays(self, start: int = 0, stop: int | None = None):
        s = slice(start, stop)
        return self.timestamps[s], self.positions[s], self.orientations[s], self.valid[s]

    def poses(self, i: int) -> TrackerPoses:
        return TrackerPoses(float(self.timestamps[i]), self.positions[i].copy(), self.orientations[i].copy(),
                            self.valid[i].copy())

    def samples(self, i: int) -> list[TrackerSample]:
        """The reports of frame i; a tracker that lost tracking reports its last known pose
        with TRACKING_VALID cleared (as a device does)."""
        out = []
        for role in self.roles:
            ok = bool(self.valid[i, role])
            out.append(TrackerSample(int(role), role, float(self.timestamps[i]), self.positions[i, role],
                                     self.orientations[i, role],
                                     TrackerStatus.TRACKING_VALID if ok else TrackerStatus.NONE))
        return out


def load_humanoid(path: str | Path) -> Clip:
    """A BVH (or .bvh.gz) file as humanoid motion."""
    from stylecast.motion.bvh import read_bvh, require_frames
    from stylecast.motion.humanoid import Retarget

    clip = require_frames(read_bvh(path), str(path))
    if tuple(clip.skeleton.names) == HUMANOID_BONES:
        return clip
    return Retarget.for_clip(clip).to_humanoid(clip)


def with_tpose(motion: Clip, seconds: float) -> Clip:
    """``motion`` preceded by ``seconds`` of T-pose at its first root position: what a
    performer does before a take so a T-pose calibration (``calibrate=tpose``) can run."""
    if not 0.0 <= seconds <= 60.0:
        raise UserError(f"--tpose {seconds} is out of range; give seconds between 0 and 60")
    n = int(round(seconds * motion.fps))
    if n == 0:
        return motion
    J = len(motion.skeleton)
    return motion.replace(rotations=np.concatenate([np.tile(rot.IDENTITY, (n, J, 1)), motion.rotations]),
                          root_positions=np.concatenate([np.tile(motion.root_positions[:1], (n, 1)),
                                                         motion.root_positions]))


def emulate_trackers(motion: Clip, points: int = 10, *, noise_mm: float = 0.0, rot_noise_deg: float = 0.0,
                     drop: float = 0.0, drop_burst: float = 6.0, mount_jitter_cm: float = 0.0,
                     mount_jitter_deg: float = 0.0, seed: int | None = 0, speed: float = 1.0,
                     rate: float | None = None) -> TrackerRecording:
    """The tracker poses a VIVE set strapped to ``motion``'s performer would report.

    ``noise_mm``: Gaussian position noise (std per axis, mm); ``rot_noise_deg``: Gaussian
    rotation noise (std of the rotation angle per axis, degrees); ``drop``: fraction of
    samples lost, in bursts of ``drop_burst`` frames on average; ``mount_jitter_*``: how far
    each strap sits from its nominal place (drawn once); ``speed``: playback rate (the
    timestamps run ``speed`` times faster than the clip); ``rate``: tracker sampling rate
    in Hz of the replayed timeline (the clip is resampled; default: the clip's own rate).
    """
    roles = roles_for_points(points)
    _check_options(noise_mm, drop, speed)
    if rate is not None:
        if not 1.0 <= rate <= 1000.0:
            raise UserError(f"--rate {rate} is out of range; give a tracker rate between 1 and 1000 Hz")
        from stylecast.motion.resample import resample

        motion = resample(motion, rate / speed)
    rng = np.random.default_rng(seed)
    pos, wrot = forward_kinematics(motion)
    T = motion.num_frames
    P = np.zeros((T, N_ROLES, 3))
    Q = np.tile(rot.IDENTITY, (T, N_ROLES, 1))
    V = np.zeros((T, N_ROLES), bool)
    sk = motion.skeleton
    for role in roles:
        mp, mq = nominal_mount(role, sk)
        if mount_jitter_cm:
            mp = mp + rng.normal(0.0, mount_jitter_cm, 3)
        if mount_jitter_deg:
            mq = rot.multiply(mq, Rotation.from_rotvec(np.radians(rng.normal(0.0, mount_jitter_deg, 3))).as_quat())
        b = HUMANOID_BONES.index(role.bone)
        P[:, role] = pos[:, b] + rot.apply(wrot[:, b], mp)
        Q[:, role] = rot.multiply(wrot[:, b], mq)
        V[:, role] = True
    if noise_mm:
        P[:, list(roles)] += rng.normal(0.0, noise_mm / 10.0, (T, len(roles), 3))
    if rot_noise_deg:
        jitter = Rotation.from_rotvec(np.radians(rng.normal(0.0, rot_noise_deg, (T * len(roles), 3)))).as_quat()
        Q[:, list(roles)] = rot.multiply(Q[:, list(roles)], jitter.reshape(T, len(roles), 4))
    if drop > 0:
        V[:, list(roles)] &= ~_dropouts(rng, T, len(roles), drop, drop_burst)
        # A lost tracker keeps reporting its last known pose (flagged invalid).
        for role in roles:
            idx = np.where(V[:, role], np.arange(T), 0)
            np.maximum.accumulate(idx, out=idx)
            P[:, role] = P[idx, role]
            Q[:, role] = Q[idx, role]
    Q = rot.canonical_hemisphere(Q, axis=0)
    return TrackerRecording(np.arange(T) / (motion.fps * speed), P, Q, V, roles)


def _check_options(noise_mm: float, drop: float, speed: float) -> None:
    if not 0.0 <= noise_mm <= 1000.0:
        raise UserError(f"--noise {noise_mm} is out of range; give millimetres between 0 and 1000")
    if not 0.0 <= drop < 1.0:
        raise UserError(f"--drop {drop} is out of range; give a fraction of samples between 0 and 0.99")
    if not 0.01 <= speed <= 100.0:
        raise UserError(f"--speed {speed} is out of range; give a playback rate between 0.01 and 100")


def _dropouts(rng, T: int, n: int, rate: float, burst: float) -> np.ndarray:
    """(T, n) lost flags from a two-state Markov chain whose lost fraction is ``rate``."""
    burst = max(burst, 1.0)
    p_lose = rate / (burst * (1.0 - rate))
    p_regain = 1.0 / burst
    u = rng.random((T, n))
    lost = np.zeros((T, n), bool)
    state = rng.random(n) < rate
    for t in range(T):
        state = np.where(state, u[t] >= p_regain, u[t] < p_lose)
        lost[t] = state
    return lost


# ------------------------------------------------------------------ sinks and pacing


class Emulator:
    """Plays a TrackerRecording into a sink in (scaled) real time on an injected clock."""

    def __init__(self, recording: TrackerRecording, clock=None):
        self.recording = recording
        self.clock = clock or RealClock()
        self.frames_sent = 0

    def run(self, sink, *, loop: bool = False, max_frames: int | None = None) -> int:
        """Send frame i at start + timestamp[i] (timestamps already include the speed).
        Returns the number of frames sent; a late clock sends without sleeping (it never
        skips frames: a tracker stream has no frames to spare)."""
        rec = self.recording
        n = len(rec)
        period = float(rec.timestamps[1] - rec.timestamps[0]) if n > 1 else 1 / 60
        start = self.clock.now()
        i = 0
        while max_frames is None or i < max_frames:
            k = i % n
            if not loop and i >= n:
                break
            lap = i // n
            due = start + lap * (rec.timestamps[-1] + period) + rec.timestamps[k]
            wait = due - self.clock.now()
            if wait > 0:
                self.clock.sleep(wait)
            samples = rec.samples(k)
            if lap:
                offset = lap * (rec.timestamps[-1] + period)
                samples = [TrackerSample(s.tracker_id, s.role, s.timestamp + offset, s.position, s.orientation,
                                         s.status) for s in samples]
            sink.send(samples)
            i += 1
            self.frames_sent += 1
        return self.frames_sent
