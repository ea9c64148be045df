"""What can touch what: surfaces, unilateral point and sphere–sphere contacts, joint stops."""

from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.contact.joint_stop import JointStop
from ucontrol.contact.plane import Plane
from ucontrol.contact.point_contact import PointContact
from ucontrol.contact.sphere_sphere_contact import SphereSphereContact
from ucontrol.contact.tangent_basis import tangent_basis

__all__ = [
    "ConstraintSet",
    "JointStop",
    "Plane",
    "PointContact",
    "SphereSphereContact",
    "tangent_basis",
]
