"""Controllers and the protocol they follow."""

from ucontrol.control.controller import ContactState, Controller
from ucontrol.control.joint_pd import JointPD
from ucontrol.control.zero_torque import ZeroTorque

__all__ = ["ContactState", "Controller", "JointPD", "ZeroTorque"]
