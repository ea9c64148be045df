"""What can touch what: surfaces, point, sphere–sphere and collision-shape contacts, stops.

Every name is imported from its module on first use, so that a scene loads only the kinds of
constraint it declares (a run of point contacts on planes loads neither the bilateral
constraints nor the collision pairs).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ucontrol._lazy_names import lazy_names

if TYPE_CHECKING:
    from ucontrol.contact.assembly import assemble
    from ucontrol.contact.bilateral import BilateralSet, FrameClosure, JointCoupling
    from ucontrol.contact.collision_pair import CollisionPair, EnvironmentShape
    from ucontrol.contact.constraint_set import ConstraintSet
    from ucontrol.contact.joint_stop import JointStop
    from ucontrol.contact.plane import Plane
    from ucontrol.contact.point_contact import PointContact
    from ucontrol.contact.sphere_sphere_contact import SphereSphereContact
    from ucontrol.contact.tangent_basis import tangent_basis

#: Each public name's module.
_MODULES = {
    "BilateralSet": "ucontrol.contact.bilateral",
    "CollisionPair": "ucontrol.contact.collision_pair",
    "ConstraintSet": "ucontrol.contact.constraint_set",
    "EnvironmentShape": "ucontrol.contact.collision_pair",
    "FrameClosure": "ucontrol.contact.bilateral",
    "JointCoupling": "ucontrol.contact.bilateral",
    "JointStop": "ucontrol.contact.joint_stop",
    "Plane": "ucontrol.contact.plane",
    "PointContact": "ucontrol.contact.point_contact",
    "SphereSphereContact": "ucontrol.contact.sphere_sphere_contact",
    "assemble": "ucontrol.contact.assembly",
    "tangent_basis": "ucontrol.contact.tangent_basis",
}

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


__getattr__ = lazy_names(__name__, _MODULES)


def __dir__() -> list[str]:
    return sorted(__all__)
