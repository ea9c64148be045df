"""Robot models over Pinocchio."""

from ucontrol.model.flexible_joints import FlexibleJoints
from ucontrol.model.robot_model import RobotModel
from ucontrol.model.symbolic_model import SymbolicModel
from ucontrol.model.urdf_path import example_robot_data_dir, resolve_urdf

__all__ = [
    "FlexibleJoints",
    "RobotModel",
    "SymbolicModel",
    "example_robot_data_dir",
    "resolve_urdf",
]
