"""A low-pass filter on the restyle's correction, between the seam blender and the foot
lock, live and offline alike.

Each word's correction is smooth by construction (``models.networks``: a cubic B-spline
over the word), but consecutive words are separate predictions and disagree where they
overlap; every switch of word (every ``hop`` frames) then turns the motion a little, and
the seam blender's spring hides the jump in pose but not the jump in acceleration.
Measured on held-out clips, that made the stream's jerk 1.2-2x the input's while a single
word's was 1.04x. So the stream's correction, r_t = output_t * input_t^-1 per bone as a
rotation vector, goes through three cascaded one-pole filters (time constant ``tau``
frames; a triple pole, so a step in r comes out continuous in value, rate and
acceleration) and is put back on the input: output'_t = exp(filtered r_t) * input_t.

The input's own motion passes at full rate: only the style correction is smoothed, and
delayed by about 3 tau frames (6 frames, 0.1 s, at the default tau of 2), which a slowly
varying posture and dynamics change tolerates. Causal, with its state carried from block
to block (``scipy.signal.lfilter`` with ``zi``): a clip filtered whole and a stream filtered
a frame at a time give the same frames. The filter starts settled on the stream's first
correction (``lfilter_zi``): a stream shown restyled from its first frame
(``words.BlendSettings.start_restyled``) would otherwise grow its correction in from
nothing over the first 3 tau frames, a pop of up to 7 degrees a frame for a 56-degree
correction. A stream that starts in pass-through starts it at rest (r = 0).
"""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter, lfilter_zi

from . import rotations as rot

CORRECTION_TAU = 2.0  # frames; measured: hop 4 jerk ratio 2.0 -> 1.05 (see models/checkpoints/MODEL_CARD.md)


def smoothstep(x: np.ndarray, low: float = 0.0, high: float = 1.0) -> np.ndarray:
    """0 up to ``low``, 1 from ``high``, 3t^2 - 2t^3 between (t the way from one to the
    other): a step with no kink at either end, so what it weighs moves in and out with zero
    slope (the foot lock's contacts and weights, the gait amplitude's gates, the tracker
    solver's holds)."""
    t = np.clip((np.asarray(x) - low) / (high - low), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def triple_pole(tau: float) -> tuple[np.ndarray, np.ndarray]:
    """lfilter's (b, a) of three cascaded one-pole low-passes of time constant ``tau``
    frames, unity gain at rest: (gain / (1 - pole z^-1))^3 as one recursion."""
    pole = np.exp(-1.0 / tau) if tau > 0 else 0.0
    return np.array([(1.0 - pole) ** 3]), np.array([1.0, -3 * pole, 3 * pole ** 2, -pole ** 3])


class CorrectionFilter:
    def __init__(self, num_bones: int, tau: float = CORRECTION_TAU):
        self.tau = float(tau)
        self._b, self._a = triple_pole(self.tau)
        self._state = np.zeros((3, num_bones * 3))
        self._settled = lfilter_zi(self._b, self._a)[:, None]  # the state per unit of a held input
        self._first = True  # no frame filtered yet: the first one settles the state

    def apply(self, inputs: np.ndarray, outputs: np.ndarray) -> np.ndarray:
        """Frames (n, J, 4) in order: the inputs and the blender's outputs -> filtered outputs."""
        if self.tau <= 0:
            return outputs
        inputs = np.asarray(inputs, dtype=np.float64)
        n, joints = inputs.shape[:2]
        correction = rot.log_map(rot.multiply(outputs, rot.inverse(inputs))).reshape(n, -1)
        self._settle_on(correction[0])
        smooth, self._state = lfilter(self._b, self._a, correction, axis=0, zi=self._state)
        return rot.multiply(rot.exp_map(smooth.reshape(n, joints, 3)), inputs)

    def _settle_on(self, correction: np.ndarray) -> None:
        """Before the stream's first frame: the state of a filter that has held this
        correction (J*3,) forever, so that frame comes out as it went in."""
        if self._first:
            self._first = False
            self._state = self._settled * correction


def filter_frames(filters: list[CorrectionFilter], inputs: np.ndarray, outputs: np.ndarray) -> np.ndarray:
    """One frame of each of several streams, (P, J, 4) inputs and outputs, each through its
    own filter, in one vectorised pass (the daemon's tick: one frame per performer, where
    numpy's per-call cost was most of the filter's); the same as each filter's ``apply``."""
    taus = {f.tau for f in filters}
    if len(taus) > 1 or min(taus) <= 0:  # (the daemon's streams share one tau)
        return np.stack([f.apply(i[None], o[None])[0] for f, i, o in zip(filters, inputs, outputs)])
    inputs = np.asarray(inputs, dtype=np.float64)
    p, joints = inputs.shape[:2]
    correction = rot.log_map(rot.multiply(outputs, rot.inverse(inputs))).reshape(1, p, -1)
    for f, first in zip(filters, correction[0]):
        f._settle_on(first)
    state = np.stack([f._state for f in filters], axis=1)  # (3, P, J*3)
    smooth, state = lfilter_one_step(filters[0]._b, filters[0]._a, correction[0], state)
    for k, f in enumerate(filters):
        f._state = state[:, k]
    return rot.multiply(rot.exp_map(smooth.reshape(p, joints, 3)), inputs)


def lfilter_one_step(b: np.ndarray, a: np.ndarray, x: np.ndarray, state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``lfilter(b, a, x[None], axis=0, zi=state)`` for the one sample the daemon's tick
    has, written out (transposed direct form II, lfilter's own; ``b`` has one coefficient).
    Hand-written because measured: lfilter loops over the channels in C, one filter each,
    215 us a tick for 32 performers' 66 channels here, against a few us for these four
    whole-array operations (tests: equal to lfilter within rounding)."""
    y = b[0] * x + state[0]
    after = np.empty_like(state)
    after[0] = state[1] - a[1] * y
    after[1] = state[2] - a[2] * y
    after[2] = -a[3] * y
    return y, after


class TriplePole:
    """``triple_pole`` over a scalar signal, its state carried from call to call."""

    def __init__(self, tau: float):
        self._b, self._a = triple_pole(tau)
        self._coefficients = (float(self._b[0]), *self._a[1:].tolist())  # b0, a1, a2, a3 for ``step``
        self._state = [0.0, 0.0, 0.0]
        self._settled = lfilter_zi(self._b, self._a).tolist()  # the state per unit of a held input

    def settle_on(self, x: float) -> None:
        """The state of a filter that has held ``x`` forever: its next output is ``x``."""
        self._state = [z * float(x) for z in self._settled]

    def run(self, x: np.ndarray) -> np.ndarray:
        y, state = lfilter(self._b, self._a, x, zi=np.asarray(self._state))
        self._state = state.tolist()
        return y

    def step(self, x: float) -> float:
        """``run`` of one value on Python floats (the daemon's case; scipy's lfilter costs
        ~50 us a call): the same recursion, in lfilter's transposed direct form II."""
        (z0, z1, z2), (b0, a1, a2, a3) = self._state, self._coefficients
        y = b0 * x + z0
        self._state = [z1 - a1 * y, z2 - a2 * y, -a3 * y]
        return y
