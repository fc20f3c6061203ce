"""Planted feet stay planted: foot contacts of the input, and a two-bone leg IK that puts
each planted foot of the restyled output back where the input put it.

A restyle changes every bone's rotation, hips and legs included, while the root
trajectory is the input's (but for the pelvis height and the pace, ``pelvis`` and
``pace``): without a fix, a foot the performer keeps still on the floor drifts with the
restyled hips and knees (the first shipped model slid planted feet by 1 cm per frame, 13x
the input). This stage runs after the seam blender on every output frame, live and
offline alike (``SeamBlender`` -> ``FootLock.apply``), so ``restyle`` and ``serve`` send
the same frames.

In short: ``FootLock.push`` finds each input frame's contacts (``contacts``), and
``FootLock.apply`` blends each planted leg of an output frame onto the input's foot by the
leg IK, in by ``ramp`` frames before a contact and out by ``release`` frames after it
(``lock``, ``legs``), with the pelvis set to the restyled legs' bend, the body's pace and
the floor (``pelvis``, ``pace``, ``solve``); each module's docstring says how and why.

The parts, one module each:
- ``settings``: ``ContactSettings`` and the named locks (``FEET``, ``--feet``; ``--pace``);
- ``contacts``: the contact test, each lock's history of the input, the lock weights;
- ``legs``: the legs' forward kinematics and the two-bone IK;
- ``lock``: ``FootLock`` (push input frames, plan output frames) and the daemon's
  one-tick forms for many locks (``push_frames``, ``plan_locks``);
- ``solve``: a plan's solve, for one lock or many in one pass (``solve_lock_jobs``), and
  the floor;
- ``pelvis``, ``pace``, ``stance``: what the body's root and the feet's targets do;
- ``amplitude``: the arms' swing and the hips' bob at the style's amounts while walking and
  running, beside the pace.
"""

from .amplitude import GaitAmplitude
from .contacts import approach, lock_kernel
from .legs import HIPS, LEG_INDEX, LEGS, knee_direction, leg_chain, solve_legs
from .lock import FootLock, plan_locks, push_frames
from .pace import MAX_PACE_RATIO, Pace
from .pelvis import PelvisHeight
from .settings import (AUTO_FEET, FEET, NO_AMPLITUDES, PACE_CHOICES, ContactSettings, amplitudes_of, check_feet,
                       check_pace, feet_for, pace_of, quick_hips_of, stance_standing_of)
from .solve import LockJob, kept_clearance, solve_lock_jobs
from .stance import StanceOffset, stance_targets

__all__ = ["AUTO_FEET", "FEET", "HIPS", "LEGS", "LEG_INDEX", "MAX_PACE_RATIO", "NO_AMPLITUDES", "PACE_CHOICES",
           "ContactSettings", "FootLock", "GaitAmplitude", "LockJob", "Pace", "PelvisHeight", "StanceOffset",
           "amplitudes_of", "approach", "check_feet", "check_pace", "feet_for", "kept_clearance", "knee_direction",
           "leg_chain", "lock_kernel", "pace_of", "plan_locks", "push_frames", "quick_hips_of", "solve_legs",
           "solve_lock_jobs", "stance_standing_of", "stance_targets"]
