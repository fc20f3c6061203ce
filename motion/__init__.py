"""The shared vocabulary of stylecast: skeletons, clips, rotations, BVH, humanoid retargeting."""

from .clip import Clip, PoseFrame, forward_kinematics, rest_positions
from .errors import UserError
from .skeleton import Skeleton

__all__ = ["Clip", "PoseFrame", "Skeleton", "UserError", "forward_kinematics", "rest_positions"]
