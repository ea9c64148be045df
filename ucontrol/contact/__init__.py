"""What can touch what: surfaces, point, sphere–sphere and collision-shape contacts, stops."""

from ucontrol.contact.assembly import assemble
from ucontrol.contact.bilateral import BilateralSet, FrameClosure, JointCoupling
from ucontrol.contact.collision_pair import CollisionPair, EnvironmentShape
from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.contact.joint_stop import JointStop
from ucontrol.contact.plane import Plane
from ucontrol.contact.point_contact import PointContact
from ucontrol.contact.sphere_sphere_contact import SphereSphereContact
from ucontrol.contact.tangent_basis import tangent_basis

__all__ = [
    "BilateralSet",
    "CollisionPair",
    "ConstraintSet",
    "EnvironmentShape",
    "FrameClosure",
    "JointCoupling",
    "JointStop",
    "Plane",
    "PointContact",
    "SphereSphereContact",
    "assemble",
    "tangent_basis",
]
