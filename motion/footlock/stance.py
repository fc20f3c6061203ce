"""Stance (``StanceOffset``, ``--feet stance``): a style stands differently (masculine feet
wide apart, feminine close together, knees and toes turned in or out), and a lock onto the
input's own ankles and knees undoes that: measured on held-out clips with the multi-style
model, windows judged masculine fell from 81 % unlocked to 11 % locked, feminine from 77 %
to 23 %, nearly all of it in the standing actions. With the stance kept, the target is the
input's ankle plus a horizontal offset (where the restyled foot stands beside the input's)
and the foot turns about the vertical as the restyled one; the knee keeps its restyled
plane. While a foot is free the offsets follow the restyled leg; while its lock blends in
before touch-down they still follow it by the share of the lock not yet set
(``stance_settle``), easing to a stop as it lands; from then on, until it lifts, they move
at most ``stance_rate`` cm (``turn_rate`` degrees) a frame, by default not at all, so a
planted foot lands where the restyled leg put it and stays there beside the input's: a
standing performer's stance changes by a step, as a real one's does (a new style chosen
live while standing shows in the feet at the next step). A foot's heading counts in
proportion to its length on the floor: a foot pointing down has none to follow. Through a
stream's first fade-in from pass-through (where it has one:
``words.BlendSettings.start_restyled``) the targets are taken at the share the fade heads
for, so a foot planted at the start stands in the restyled stance from the first frame
instead of sliding into it as the body fades in; through an offline clip's mirrored lead-in
a planted foot takes the mean of the restyled stance over its contact (``stance_lead_mean``),
not one frame of it. A style whose restyled standing stance is wrong for it keeps only a
share of the stance's place while the performer stands (``stance_standing``, by the input's
low-passed speed over ground), all of it walking. Each model kind names its lock (``FEET``,
``--feet auto``), and a checkpoint may name another (``train --feet``).
"""

from __future__ import annotations

import numpy as np

from ..smoothing import TriplePole
from .pace import TELEPORT_STEP
from .settings import MOVING_SPEED, STANDING_SPEED, ContactSettings


class StanceOffset:
    """Where each locked foot stands against the input's (see the module docstring): its
    ankle's horizontal offset (x, z, cm) and its turn about the vertical (radians); state
    carried from block to block like ``PelvisHeight``."""

    def __init__(self, settings: ContactSettings):
        self.cap, self.rate = settings.stance_cap, settings.stance_rate
        self.turn_cap, self.turn_rate = np.radians(settings.turn_cap), np.radians(settings.turn_rate)
        self.turn_unsure, self.turn_sure = settings.turn_unsure, settings.turn_sure
        self.settle = settings.stance_settle
        self.lead_mean = settings.stance_lead_mean
        self._lead_count = [0, 0]  # frames each foot has been fully locked in the lead-in
        self._landed = [False, False]  # each foot reached its full lock since it was last free
        self._offset: list | None = None  # [[x, z, turn], [x, z, turn]] of the last frame
        # Before this frame the offsets follow the restyle freely: an offline clip's mirrored
        # lead-in, which is not shown (0 for a stream); a foot planted there takes the mean
        # over its contact so far (``lead_mean``), which a standing take then keeps.
        self.free_until = 0
        # A stream that fades the restyle in from pass-through (``start_restyled=False``)
        # shows its stance only in part until this frame (``first_fade_end``; 0 for a stream
        # restyled from its first frame). Its targets are then taken at the share the fade
        # heads for (``aim``, the stream's intensity): the restyled offset over the share shown
        # so far, low-passed as the correction is (``fade_tau``). So a planted foot stands in
        # the restyled stance from the first frame while the body fades in. Following the
        # fading stance instead slid planted feet 3.2-4.8x the input's over held-out takes
        # played live with the multi-style model at the default hop (1.2-1.3x this way, for
        # 4-8 points of active, masculine and youthful's style reading: the model card's
        # "The stance through a stream's fade-in"); holding the input's stance kept a
        # standing performer's feet there for good (width 15.1 cm against the input's 15.2
        # and the restyle's 7-15, a feminine raise-up-both-hands take).
        self.fade_until = 0
        self.aim = 1.0
        self._shown: TriplePole | None = None  # the shown share's low-pass (``for_fade``)
        self._fading = False  # the first fade's first frame seen
        # The input's speed over ground, low-passed as the pace's (``stance_standing``);
        # followed whatever the share, so a style set live starts from the performer's speed.
        self._speed = TriplePole(settings.pace_tau)
        self._previous_xz: tuple | None = None  # the last input root's (x, z)
        self._last_step = 0.0  # ...its last step that was not a teleport
        self._speed_now = 0.0
        self._stepped = False  # the first step seen (the low-pass starts settled on it)
        self.set_standing(settings.stance_standing)

    def set_standing(self, share: float) -> None:
        """The share of the stance's place kept while the performer stands (a new model or
        style mix: ``stance_standing``); a planted foot keeps where it stands until it lifts."""
        self.standing = min(max(float(share), 0.0), 1.0)

    def for_fade(self, fade_until: int, fade_tau: float) -> None:
        """A stream's first fade from pass-through ends at frame ``fade_until``, its correction
        low-passed over ``fade_tau`` frames (see ``fade_until`` above)."""
        self.fade_until = int(fade_until)
        self._shown = TriplePole(fade_tau) if fade_tau > 0 else None

    def track(self, t0: int, own: tuple, restyled: tuple, weights: np.ndarray,
              shown: np.ndarray | None = None, roots: np.ndarray | None = None) -> np.ndarray | None:
        """Frames t0 .. t0+n-1 in order: the input's and the restyled (ankle, ball)
        positions, each (n, 2, 3), each foot's lock weight (n, 2: 0 free, 1 fully locked),
        the share of the restyle shown in each frame (n,; None: all of it) and the input's
        roots (n, 3; None: its speed held) -> the lock targets' offsets from the input's feet
        (n, 2, 3: x, z in cm and the turn in radians), or None when off."""
        if self.cap <= 0:
            return None
        wanted, sure = stance_targets(own, restyled, self.cap, self.turn_cap, self.turn_unsure, self.turn_sure)
        shown = [1.0] * len(wanted) if shown is None else np.broadcast_to(shown, (len(wanted),)).tolist()
        roots_xz = None if roots is None else np.asarray(roots)[:, [0, 2]].tolist()
        return np.array(self.follow(t0, wanted.tolist(), np.asarray(weights, float).tolist(), sure.tolist(), shown,
                                    roots_xz))

    def follow(self, t0: int, wanted: list, weights: list, sure: list, shown: list,
               roots_xz: list | None = None) -> list:
        """``track``'s recurrence over frames t0 .. t0+n-1 on Python floats: the targets
        (``stance_targets``), the feet's lock weights, how sure each turn is, the share of
        the restyle shown and the input root's [x, z] (None: its speed held), per frame as
        nested lists -> the offsets, the same nesting (new lists). A rate limit is a
        recurrence; on floats because the daemon runs it one frame at a time per performer
        (numpy's per-call cost would be most of it)."""
        if t0 < self.fade_until:
            wanted = [self._at_aim(t0 + i, frame, share) for i, (frame, share) in enumerate(zip(wanted, shown))]
        wanted = [self._placed(frame, None if roots_xz is None else roots_xz[i]) for i, frame in enumerate(wanted)]
        current = self._offset if self._offset is not None else wanted[0]
        out = []
        for i, (frame, weight, certainty) in enumerate(zip(wanted, weights, sure)):
            settled = t0 + i >= self.free_until
            moved = []
            for foot in (0, 1):
                (x, z, turn), (wx, wz, wturn) = current[foot], frame[foot]
                dx, dz, dturn = wx - x, wz - z, (wturn - turn) * certainty[foot]
                w = weight[foot]
                if w >= 1.0 or w <= 0.0:  # fully locked, or free again
                    self._landed[foot] = w >= 1.0
                if not settled and self.lead_mean:
                    # The lead-in (``stance_lead_mean``): a foot fully locked there stands at the mean
                    # of the restyled offsets over its contact so far, not at its last frame's.
                    self._lead_count[foot] = self._lead_count[foot] + 1 if w >= 1.0 else 0
                    share = 1.0 / max(self._lead_count[foot], 1)
                    dx, dz, dturn = dx * share, dz * share, dturn * share
                if w > 0 and settled:
                    # Settling (``stance_settle``): while the lock blends in, before the foot first
                    # lands, the offset still moves by the share of the lock not yet set, so it
                    # eases to a stop at touch-down; landed, it holds until the foot is free.
                    ease = 1.0 - w if self.settle and not self._landed[foot] else 0.0
                    step = (dx * dx + dz * dz) ** 0.5
                    allowed = max(self.rate, ease * step)
                    if step > allowed:
                        dx, dz = dx * allowed / step, dz * allowed / step
                    allowed = max(self.turn_rate, ease * abs(dturn))
                    dturn = min(max(dturn, -allowed), allowed)
                moved.append([x + dx, z + dz, turn + dturn])
            current = moved
            out.append(current)
        self._offset = current
        return out

    def _placed(self, frame: list, root_xz: list | None) -> list:
        """A frame's targets [[x, z, turn], ...] -> with the share of the stance's place
        wanted at it (``stance_standing``), the input's speed moved on by its root's [x, z]
        (None: held)."""
        place = self._place_share(root_xz)
        return frame if place >= 1.0 else [[x * place, z * place, turn] for x, z, turn in frame]

    def _place_share(self, root_xz: list | None) -> float:
        """The share of the stance's place wanted at this frame (``stance_standing``), the
        input's speed over ground moved on by its root's [x, z] (None: held)."""
        if root_xz is not None:
            x, z = root_xz
            if self._previous_xz is None:  # the stream's first frame: no step yet
                self._previous_xz = (x, z)
            else:
                step = ((x - self._previous_xz[0]) ** 2 + (z - self._previous_xz[1]) ** 2) ** 0.5
                if step > TELEPORT_STEP:  # a looped clip or a tracker glitch (``Pace``): not a speed
                    step = self._last_step
                elif not self._stepped:
                    self._speed.settle_on(step)  # the first step: settled on it, as the pace's
                    self._stepped = True
                self._previous_xz, self._last_step = (x, z), step
                self._speed_now = self._speed.step(step)
        if self.standing >= 1.0:
            return 1.0
        moving = min(max((self._speed_now - STANDING_SPEED) / (MOVING_SPEED - STANDING_SPEED), 0.0), 1.0)
        return self.standing + (1.0 - self.standing) * moving

    def _at_aim(self, t: int, frame: list, share: float) -> list:
        """Frame t's targets [[x, z, turn], ...] of a restyle shown at ``share`` -> at the
        share the stream's first fade heads for (``fade_until``), within the caps."""
        if self._shown is not None:
            if not self._fading:  # the stream's first frame: the low-pass starts settled, as the correction's
                self._shown.settle_on(share)
            share = self._shown.step(share)
        self._fading = True
        if t >= self.fade_until or share < 1e-3 or share >= self.aim:  # (nothing shown: nothing to scale)
            return frame
        scale, out = self.aim / share, []
        for x, z, turn in frame:
            length = (x * x + z * z) ** 0.5
            fit = min(scale, self.cap / length) if length > 0 else scale
            out.append([x * fit, z * fit, min(max(turn * scale, -self.turn_cap), self.turn_cap)])
        return out


def stance_targets(own: tuple, restyled: tuple, cap, turn_cap, turn_unsure, turn_sure) -> tuple:
    """Where ``StanceOffset`` wants each locked foot: the input's and the restyled (ankle,
    ball) positions, each (n, 2, 3), and the settings (numbers, or one per row shaped to
    broadcast: (n, 1, 1) for the caps, (n, 1) for the turn's certainty band) -> the wanted
    offsets (n, 2, 3: x, z in cm within ``cap``, the turn in radians within ``turn_cap``)
    and how sure each turn is (n, 2: 0 below ``turn_unsure`` cm of foot on the floor, 1
    from ``turn_sure``)."""
    foot_out, foot_in = restyled[1] - restyled[0], own[1] - own[0]  # ankle to ball
    turn = _heading(foot_out) - _heading(foot_in)
    turn = (turn + np.pi) % (2 * np.pi) - np.pi
    on_floor = np.minimum(_floor_length(foot_out), _floor_length(foot_in))
    sure = np.clip((on_floor - turn_unsure) / (turn_sure - turn_unsure), 0.0, 1.0)
    wanted = np.concatenate([(restyled[0] - own[0])[..., [0, 2]], turn[..., None]], axis=-1)
    length = np.linalg.norm(wanted[..., :2], axis=-1, keepdims=True)
    wanted = np.concatenate([wanted[..., :2] * np.minimum(1.0, cap / np.maximum(length, 1e-9)),
                             np.clip(wanted[..., 2:], -turn_cap, turn_cap)], axis=-1)
    return wanted, sure


def _heading(v: np.ndarray) -> np.ndarray:
    """(..., 3) -> the angle about the vertical (radians) that turns +Z onto v's floor part."""
    return np.arctan2(v[..., 0], v[..., 2])


def _floor_length(v: np.ndarray) -> np.ndarray:
    """(..., 3) -> the length of v's floor part (the vertical is y)."""
    return np.hypot(v[..., 0], v[..., 2])
