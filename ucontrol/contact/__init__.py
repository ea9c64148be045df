"""What can touch what: surfaces, unilateral point contacts and joint stops."""

from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.contact.joint_stop import JointStop
from ucontrol.contact.plane import Plane
from ucontrol.contact.point_contact import PointContact

__all__ = ["ConstraintSet", "JointStop", "Plane", "PointContact"]
