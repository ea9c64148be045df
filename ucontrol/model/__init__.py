"""Robot models over Pinocchio.

:class:`SymbolicModel` (casadi) is imported on first use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ucontrol._lazy_names import lazy_names
from ucontrol.model.flexible_joints import FlexibleJoints
from ucontrol.model.joint_friction import JointFriction
from ucontrol.model.robot_model import RobotModel
from ucontrol.model.urdf_path import example_robot_data_dir, resolve_urdf

if TYPE_CHECKING:
    from ucontrol.model.symbolic_model import SymbolicModel

__all__ = [
    "FlexibleJoints",
    "JointFriction",
    "RobotModel",
    "SymbolicModel",
    "example_robot_data_dir",
    "resolve_urdf",
]


__getattr__ = lazy_names(__name__, {"SymbolicModel": "ucontrol.model.symbolic_model"})
