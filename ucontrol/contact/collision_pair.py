"""Declared contact pairs of collision shapes: a link against an environment shape or a link.

The shapes of a link are the ``<collision>`` elements of its URDF; the environment's are
declared here (:class:`EnvironmentShape`). :class:`~ucontrol.contact.ConstraintSet` turns the
pairs into unilateral constraints through
:class:`~ucontrol.contact.collision_geometry.CollisionGeometry`, built (and Pinocchio's
geometry model loaded) only when a scene declares a pair.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol._validation import as_float, as_in_interval, as_positive, as_vector
from ucontrol.exceptions import InvalidParameterError

#: Environment shapes a scene may declare.
SHAPE_TYPES = ("halfspace", "box", "sphere")
#: How a pair's contact points are chosen (:class:`CollisionPair`).
POINT_RULES = ("auto", "witness")


@dataclass(frozen=True, kw_only=True)
class EnvironmentShape:
    """A shape fixed in the world.

    Attributes:
        name: Label used in logs and errors.
        type: ``"halfspace"`` (the side ``normal · (p - position) >= 0`` is free), ``"box"``
            or ``"sphere"``.
        position: Centre of the box or sphere, or a point of the halfspace's boundary, in
            world coordinates in [m], shape (3,).
        rpy: Roll, pitch, yaw of the box in [rad], shape (3,) (URDF convention).
        normal: Unit normal of the halfspace pointing into the free side, shape (3,)
            (normalised on creation).
        size: Side lengths of the box in [m], shape (3,).
        radius: Radius of the sphere in [m].
    """

    name: str
    type: str
    position: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    rpy: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    normal: NDArray[np.float64] = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    size: NDArray[np.float64] = field(default_factory=lambda: np.ones(3))
    radius: float = 1.0

    def __post_init__(self) -> None:
        if self.type not in SHAPE_TYPES:
            raise InvalidParameterError(f"type of shape {self.name!r}", self.type, str(SHAPE_TYPES))
        object.__setattr__(self, "position", as_vector("position", self.position, 3))
        object.__setattr__(self, "rpy", as_vector("rpy", self.rpy, 3))
        normal = as_vector("normal", self.normal, 3)
        norm = float(np.linalg.norm(normal))
        if norm < 1e-12:
            raise InvalidParameterError("normal", self.normal, "a non-zero vector")
        object.__setattr__(self, "normal", normal / norm)
        size = as_vector("size", self.size, 3)
        if not np.all(size > 0.0):
            raise InvalidParameterError("size", self.size, "three positive side lengths")
        object.__setattr__(self, "size", size)
        object.__setattr__(self, "radius", as_positive("radius", self.radius))

    @property
    def placement(self) -> pin.SE3:
        """Pose of the shape in the world (identity rotation for a sphere)."""
        return pin.SE3(pin.rpy.rpyToMatrix(self.rpy), self.position)


@dataclass(frozen=True, kw_only=True)
class CollisionPair:
    """The collision shapes of link ``link`` cannot penetrate ``other``.

    ``other`` is an environment shape or the name of another link. Every ``<collision>``
    element of ``link`` (and of ``other`` when it is a link) takes part; each gives one or more
    unilateral constraints (module :mod:`ucontrol.contact.collision_geometry`).

    Attributes:
        link: Name of a URDF link with ``<collision>`` elements.
        other: An environment shape, or the name of another link with ``<collision>``
            elements.
        restitution: Newton's coefficient of restitution in [0, 1].
        friction: Coulomb coefficient, >= 0 (0: frictionless).
        points: ``"auto"``: against a halfspace, the vertices of boxes and meshes, the centre
            of spheres and points of the rims of cylinders, each a constraint (a face contact
            rests on its corners); elsewhere the witness point of coal's distance.
            ``"witness"``: always one witness point per pair of shapes.
        name: Label used in logs; default ``"<link>/<other>"``.
    """

    link: str
    other: EnvironmentShape | str
    restitution: float = 0.0
    friction: float = 0.0
    points: str = "auto"
    name: str = ""

    def __post_init__(self) -> None:
        if isinstance(self.other, str) and self.other == self.link:
            raise InvalidParameterError("other", self.other, "a link other than link")
        friction = as_float("friction", self.friction)
        if friction < 0.0:
            raise InvalidParameterError("friction", self.friction, ">= 0")
        object.__setattr__(self, "friction", friction)
        object.__setattr__(
            self, "restitution", as_in_interval("restitution", self.restitution, 0.0, 1.0)
        )
        if self.points not in POINT_RULES:
            raise InvalidParameterError("points", self.points, f"one of {POINT_RULES}")
        if not self.name:
            object.__setattr__(self, "name", f"{self.link}/{self.other_name}")

    @property
    def other_name(self) -> str:
        """Name of the other shape or link."""
        return self.other if isinstance(self.other, str) else self.other.name
