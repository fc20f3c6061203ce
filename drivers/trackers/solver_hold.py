"""Hold of lost trackers and blend back when they return.

Works on bone poses (position, rotation) per tracker role, before the IK: the IK never
knows whether a pose is live, held or blending, except through ``live`` (how live each
role is), which strengthens its pole hint while a hand or foot is held.

While every tracker is live (the common case) a call costs a few numpy calls. While one is
lost or blending back, the work is numpy vectorised over each stretch of frames: ideal
for recordings; on the live path, a frame then costs a few hundred µs (numpy calls on
one-frame arrays), still some 50x the tracker rate.
"""

from __future__ import annotations

import numpy as np

from stylecast.motion import rotations as rot

from stylecast.drivers.trackers.solver_body import N_ROLES, B, R
from stylecast.drivers.trackers.solver_calibration import Calibration
from stylecast.drivers.trackers.solver_math import _rotate, _swing
from stylecast.motion.smoothing import smoothstep


def _relative(hp, hq, p, q):
    inv = rot.inverse(hq)
    return _rotate(inv, p - hp), rot.multiply(inv, q)


def _compose(hp, hq, rp, rq):
    return hp + _rotate(hq, rp), rot.multiply(hq, rq)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of every run of True in a 1-D boolean array."""
    edges = np.zeros(len(mask) + 2, np.int8)  # (np.r_ costs ~20 µs a call: it is on the live path)
    edges[1:-1] = mask
    d = np.diff(edges)
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


class _HoldBlend:
    """Hold of lost trackers and blend back on return (see the module doc), on bone poses
    (position, rotation) per role:

    * a lost limb / head bone keeps its last output pose relative to the hips, so it is
      carried along by the body;
    * a lost waist sits between the hip joints the two thigh trackers imply (10 points),
      turned from its last rotation to match them; without them it keeps its last
      rotation and follows the headset's translation; without that it stays put;
    * a returning tracker blends from that estimate to its live pose over ``blend_time``
      seconds (smoothstep: no step in position and none in velocity at either end).

    ``run`` takes any number of consecutive frames and carries its state over to the next
    call: the live path feeds one frame at a time, ``solve_batch`` a whole recording, and
    both get the same output. Work is vectorised over each stretch of a lost or returning
    tracker; frames where every tracker is live cost nothing.
    """

    def __init__(self, cal: Calibration, blend_time: float):
        self.cal = cal
        self.roles = tuple(cal.roles)
        self._role_index = np.array(self.roles, dtype=np.intp)
        self._all_roles = len(set(self.roles)) == N_ROLES
        self._has_head = R.HMD in self.roles
        self.limb_roles = tuple(r for r in self.roles if r != R.WAIST)
        self.blend_time = max(float(blend_time), 1e-6)
        off = cal.skeleton.offsets
        self._hip_axis = off[B["LeftUpperLeg"]] - off[B["RightUpperLeg"]]  # in the hips frame
        self._hip_mid = 0.5 * (off[B["LeftUpperLeg"]] + off[B["RightUpperLeg"]])
        self._has_knees = R.LEFT_KNEE in self.roles and R.RIGHT_KNEE in self.roles
        self.reset()

    def reset(self) -> None:
        self.prev_p = None  # last output (N_ROLES, 3), None before the first frame
        self.prev_q = None
        self.prev_head = None  # the live headset pose of the last frame, if it was valid
        self.lost = np.zeros(N_ROLES, bool)
        self._any_lost = False  # self.lost.any() and self.returned_at.max(), for the common case
        self._last_return = -np.inf
        self.returned_at = np.full(N_ROLES, -np.inf)
        self.held_p = np.zeros((N_ROLES, 3))  # relative to the hips
        self.held_q = np.tile(rot.IDENTITY, (N_ROLES, 1))
        self.waist_mode = ""  # "knees", "head" or "still" while the waist is estimated
        self.waist_anchor: tuple = ()
        self.last_local = None  # the solver's last output rotations (sign continuity)

    def run(self, ts: np.ndarray, live_p: np.ndarray, live_q: np.ndarray, valid: np.ndarray):
        """Frames (T,), live bone poses (T, 10, 3/4), valid (T, 10) -> output poses and how
        live each role is (T, 10): 1 live, 0 held, in between while blending back; None
        when every role is live throughout (the common case, which costs a few µs).
        """
        # Busy: a tracker is lost or blending back. ts - (latest return) < blend_time is
        # exactly "any role's ts - returned_at < blend_time" (rounding is monotonic).
        busy = self._any_lost or ts[0] - self._last_return < self.blend_time
        if not busy and (valid.all() if self._all_roles else valid[:, self._role_index].all()):
            # The common case: nothing to do but remember the last frame (its headset is live).
            self.prev_p, self.prev_q = live_p[-1].copy(), live_q[-1].copy()
            self.prev_head = (self.prev_p[R.HMD], self.prev_q[R.HMD]) if self._has_head else None
            return live_p, live_q, None
        live = np.ones((len(ts), N_ROLES))
        out_p, out_q = live_p.copy(), live_q.copy()
        # Roles live all along and not blending: _waist / _limb would leave their state as
        # it is and return (the lost flag is clear, so nothing counts as a return), so skip
        # them, found for all roles at once (most roles in most busy frames).
        steady = ~self.lost & valid.all(axis=0) & ~(ts[:, None] - self.returned_at < self.blend_time).any(axis=0)
        if R.WAIST in self.roles:
            if steady[R.WAIST]:
                self.waist_mode = ""
            else:
                self._waist(ts, live_p, live_q, valid, out_p, out_q, live)
        for role in self.limb_roles:
            if not steady[role]:
                self._limb(role, ts, live_p, live_q, valid, out_p, out_q, live)
        self._any_lost = bool(self.lost.any())
        self._last_return = float(self.returned_at.max())
        self._remember(out_p[-1], out_q[-1], live_p[-1, R.HMD], live_q[-1, R.HMD], valid[-1])
        return out_p, out_q, live

    def _remember(self, p, q, head_p, head_q, valid) -> None:
        self.prev_p, self.prev_q = p.copy(), q.copy()
        self.prev_head = (head_p.copy(), head_q.copy()) if R.HMD in self.roles and valid[R.HMD] else None

    def _returns(self, role, ts, v):
        """Per frame: the time the role last came back (ffill), updating the state."""
        back = v & ~np.concatenate(([~self.lost[role]], v[:-1]))  # valid now, lost the frame before
        ret = np.where(back, ts, -np.inf)
        ret[0] = max(ret[0], self.returned_at[role])
        ret = np.maximum.accumulate(ret)
        self.returned_at[role] = ret[-1]
        self.lost[role] = not v[-1]
        return ret

    def _before(self, t, out_p, out_q):
        """The output pose of every role at the frame before chunk index t (None: none yet)."""
        if t > 0:
            return out_p[t - 1], out_q[t - 1]
        return (self.prev_p, self.prev_q) if self.prev_p is not None else (None, None)

    def _limb(self, role, ts, live_p, live_q, valid, out_p, out_q, live) -> None:
        v = valid[:, role]
        continuing = self.lost[role]  # a gap that began in an earlier chunk
        ret = self._returns(role, ts, v)
        blending = v & (ts - ret < self.blend_time)
        if v.all() and not blending.any():
            return
        W = R.WAIST
        events = [(g0, g1) for g0, g1 in _runs(~v)]
        if blending[0] and not (events and events[0][0] == 0):
            events.insert(0, (0, 0))  # a blend carried over from the previous chunk
        for k, (g0, g1) in enumerate(events):
            if g1 > g0:  # the gap: hold relative to the hips
                if not (g0 == 0 and continuing):
                    pp, pq = self._before(g0, out_p, out_q)
                    if pp is None:  # lost from the very start: the calibrated relation
                        rest = self.cal.rest_relative[role]
                        self.held_p[role], self.held_q[role] = rest[:3], rest[3:]
                    else:
                        self.held_p[role], self.held_q[role] = _relative(pp[W], pq[W], pp[role], pq[role])
                out_p[g0:g1, role], out_q[g0:g1, role] = _compose(out_p[g0:g1, W], out_q[g0:g1, W],
                                                                  self.held_p[role], self.held_q[role])
                live[g0:g1, role] = 0.0
            nxt = events[k + 1][0] if k + 1 < len(events) else len(ts)
            w = np.arange(g1, nxt)
            w = w[blending[w]]
            if len(w):  # coming back: from the held pose to the live one, relative to the hips
                a = smoothstep((ts[w] - ret[w]) / self.blend_time)
                lp, lq = _relative(out_p[w, W], out_q[w, W], live_p[w, role], live_q[w, role])
                rp = self.held_p[role] + a[:, None] * (lp - self.held_p[role])
                rq = rot.slerp(np.broadcast_to(self.held_q[role], lq.shape), lq, a)
                out_p[w, role], out_q[w, role] = _compose(out_p[w, W], out_q[w, W], rp, rq)
                live[w, role] = a

    def _waist(self, ts, live_p, live_q, valid, out_p, out_q, live) -> None:
        W, H = R.WAIST, R.HMD
        v = valid[:, W]
        ret = self._returns(W, ts, v)
        estimate = ~v | (ts - ret < self.blend_time)
        if not estimate.any():
            self.waist_mode = ""
            return
        head_ok = valid[:, H] if H in self.roles else np.zeros(len(ts), bool)
        knees_ok = (valid[:, R.LEFT_KNEE] & valid[:, R.RIGHT_KNEE]) if self._has_knees else np.zeros(len(ts), bool)
        mode = np.where(knees_ok, 1, np.where(head_ok, 2, 3)) * estimate
        names = {1: "knees", 2: "head", 3: "still"}
        start = np.flatnonzero(np.diff(np.concatenate(([0], mode))) != 0)
        stops = np.append(start[1:], len(ts))
        for t0, t1 in zip(start, stops):
            m = names.get(int(mode[t0]))
            if m is None:
                continue
            if not (t0 == 0 and self.waist_mode == m):
                self._anchor(m, t0, live_p, live_q, valid, out_p, out_q)
            self.waist_mode = m
            sl = slice(t0, t1)
            ep, eq = self._estimate(m, sl, live_p, live_q)
            a = np.where(v[sl], smoothstep((ts[sl] - ret[sl]) / self.blend_time), 0.0)
            out_p[sl, W] = ep + a[:, None] * (live_p[sl, W] - ep)
            out_q[sl, W] = rot.slerp(eq, live_q[sl, W], a)
            live[sl, W] = a
        if not estimate[-1]:
            self.waist_mode = ""

    def _anchor(self, mode, t0, live_p, live_q, valid, out_p, out_q) -> None:
        """What the estimate keeps from the output just before it starts."""
        W, H = R.WAIST, R.HMD
        pp, pq = self._before(t0, out_p, out_q)
        if pp is not None:
            hp, hq = pp[W], pq[W]
        else:  # nothing seen yet: from the headset and the calibrated head-to-hips relation
            rest = self.cal.rest_relative[H]
            if H in self.roles and valid[t0, H]:
                hq = rot.multiply(live_q[t0, H], rot.inverse(rest[3:]))
                hp = live_p[t0, H] - _rotate(hq, rest[:3])
            else:
                hp, hq = np.zeros(3), rot.IDENTITY.copy()
        if mode == "head":
            if t0 > 0 and valid[t0 - 1, H]:
                head = live_p[t0 - 1, H]
            elif t0 == 0 and self.prev_head is not None:
                head = self.prev_head[0]
            else:
                head = live_p[t0, H]
            self.waist_anchor = (hp - head, hq)
        else:
            self.waist_anchor = (hp, hq)

    def _estimate(self, mode, sl, live_p, live_q):
        n = sl.stop - sl.start
        if mode == "knees":
            # Both thigh trackers give the hip joints: the hips sit between them, turned
            # from their anchored rotation so their left axis runs from right to left hip.
            q0 = np.broadcast_to(self.waist_anchor[1], (n, 4))
            left = live_p[sl, R.LEFT_KNEE] - live_p[sl, R.RIGHT_KNEE]
            hq = rot.multiply(_swing(_rotate(q0, self._hip_axis), left), q0)
            mid = 0.5 * (live_p[sl, R.LEFT_KNEE] + live_p[sl, R.RIGHT_KNEE])
            return mid - _rotate(hq, self._hip_mid), hq
        if mode == "head":
            # The hips keep their rotation and follow the headset's translation (people
            # turn and nod their heads without their hips).
            offset, hq = self.waist_anchor
            return live_p[sl, R.HMD] + offset, np.broadcast_to(hq, (n, 4)).copy()
        hp, hq = self.waist_anchor
        return np.broadcast_to(hp, (n, 3)).copy(), np.broadcast_to(hq, (n, 4)).copy()
