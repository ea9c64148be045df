"""Robot models over Pinocchio.

:class:`SymbolicModel` (casadi) is imported on first use.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

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


def __getattr__(name: str) -> Any:
    if name == "SymbolicModel":
        return import_module("ucontrol.model.symbolic_model").SymbolicModel
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
