"""Declared contact pairs of collision shapes: a link against an environment shape or a link.

The shapes of a link are the ``<collision>`` elements of its URDF; the environment's are
declared here (:class:`EnvironmentShape`), fixed or carried by a prescribed translation
(:mod:`ucontrol.contact.surface_motion`). :class:`~ucontrol.contact.ConstraintSet` turns the
pairs into unilateral constraints through
:class:`~ucontrol.contact.collision_geometry.CollisionGeometry`, built (and Pinocchio's
geometry model loaded) only when a scene declares a pair.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol._validation import as_float, as_in_interval, as_positive, as_vector
from ucontrol.exceptions import InvalidParameterError

if TYPE_CHECKING:
    from ucontrol.contact.surface_motion import SurfaceMotion

#: Environment shapes a scene may declare.
SHAPE_TYPES = ("halfspace", "box", "sphere", "mesh")
#: How a pair's contact points are chosen (:class:`CollisionPair`).
POINT_RULES = ("auto", "witness")


@dataclass(frozen=True, kw_only=True)
class EnvironmentShape:
    """A shape of the environment, fixed in the world or translated by a prescribed motion.

    With a ``motion`` x(t) the shape translates without turning: at time t it is where it is
    declared, moved by x(t) (its gaps are time-dependent, :mod:`ucontrol.contact.surface_motion`).

    Attributes:
        name: Label used in logs and errors.
        type: ``"halfspace"`` (the side ``normal · (p - position) >= 0`` is free), ``"box"``,
            ``"sphere"`` or ``"mesh"`` (the convex hull of the mesh file's vertices, as a
            URDF ``<mesh>`` collision element stands for its hull).
        position: Centre of the box or sphere, the origin of the mesh's frame, or a point of
            the halfspace's boundary, in world coordinates in [m], shape (3,) (at x = 0).
        rpy: Roll, pitch, yaw of the box or mesh in [rad], shape (3,) (URDF convention).
        normal: Unit normal of the halfspace pointing into the free side, shape (3,)
            (normalised on creation).
        size: Side lengths of the box in [m], shape (3,).
        radius: Radius of the sphere in [m].
        mesh: Path of the mesh file (STL, OBJ, DAE: any format coal's loader reads), for
            ``type = "mesh"``; loaded when the pair's rows are built.
        scale: Scale factors of the mesh's coordinates along its axes, shape (3,), > 0.
        motion: Prescribed translation of the shape (a
            :class:`~ucontrol.contact.surface_motion.SurfaceMotion`), or None when fixed;
            checked finite and differentiable at t = 0 on creation; a plain function is
            wrapped in :class:`~ucontrol.contact.surface_motion.UserMotion`, which checks its
            values finite at every call.
    """

    name: str
    type: str
    position: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    rpy: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    normal: NDArray[np.float64] = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    size: NDArray[np.float64] = field(default_factory=lambda: np.ones(3))
    radius: float = 1.0
    mesh: Path | None = None
    scale: NDArray[np.float64] = field(default_factory=lambda: np.ones(3))
    motion: SurfaceMotion | None = None

    def __post_init__(self) -> None:
        if self.type not in SHAPE_TYPES:
            raise InvalidParameterError(f"type of shape {self.name!r}", self.type, str(SHAPE_TYPES))
        if self.type == "mesh":
            if self.mesh is None:
                raise InvalidParameterError(
                    f"mesh of shape {self.name!r}", None, "the path of a mesh file"
                )
            object.__setattr__(self, "mesh", Path(self.mesh))
        scale = as_vector("scale", self.scale, 3)
        if not np.all(scale > 0.0):
            raise InvalidParameterError("scale", self.scale, "three positive factors")
        object.__setattr__(self, "scale", scale)
        if self.motion is not None:
            if not callable(self.motion):
                raise InvalidParameterError(
                    f"motion of shape {self.name!r}",
                    self.motion,
                    "a function of t giving (displacement, velocity, acceleration)",
                )
            from ucontrol.contact.surface_motion import (
                MotionSum,
                Polynomial,
                Sinusoid,
                UserMotion,
                check_motion,
            )

            if not isinstance(self.motion, Sinusoid | Polynomial | UserMotion | MotionSum):
                # A plain function: its values checked finite at every call.
                object.__setattr__(self, "motion", UserMotion(self.motion))
            assert self.motion is not None
            check_motion(self.motion, np.zeros(1))
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
