"""Robot models over Pinocchio."""

from ucontrol.model.robot_model import RobotModel
from ucontrol.model.urdf_path import example_robot_data_dir, resolve_urdf

__all__ = ["RobotModel", "example_robot_data_dir", "resolve_urdf"]
