"""What a scene declares, checked: the fields of a :class:`~ucontrol.scene.Scene`.

Apart from :mod:`ucontrol.scene.scene` so that the builders that read a scene
(:mod:`~ucontrol.scene.integrator_builders`, :mod:`~ucontrol.scene.controller_builders`) and
the scene that calls them do not import each other.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ucontrol._validation import as_positive, as_vector
from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.contact.point_contact import PointContact
from ucontrol.exceptions import InvalidParameterError, SceneError
from ucontrol.model.flexible_joints import FlexibleJoints
from ucontrol.model.inertia_check import check_inertias, check_mass_matrix
from ucontrol.model.joint_friction import JointFriction
from ucontrol.model.robot_model import RobotModel
from ucontrol.scene.integrator_settings import IntegratorSettings

if TYPE_CHECKING:  # the kinds a scene may not declare (:mod:`~ucontrol.scene.scene_table`)
    from ucontrol.contact.bilateral import BilateralConstraint
    from ucontrol.contact.clearance_joint import ClearanceJoint
    from ucontrol.contact.collision_pair import CollisionPair
    from ucontrol.contact.joint_stop import JointStop
    from ucontrol.contact.sphere_sphere_contact import SphereSphereContact
    from ucontrol.scene.push import Push
    from ucontrol.sensors.sensor_settings import ActuatorSettings, SensorSettings


@dataclass(frozen=True, kw_only=True)
class SceneData:
    """What a scene declares: a robot, what it can touch, its initial state, its settings.

    The fields of :class:`~ucontrol.scene.Scene`, checked when it is made; the builders of its
    integrator and controller read them (and a :class:`~ucontrol.scene.Scene` is one).

    Attributes:
        name: Label used in logs.
        robot: The robot.
        contacts: Point contacts.
        stops: Joint stops.
        sphere_contacts: Contacts between two spheres on robot frames.
        collision_pairs: Pairs of collision shapes (URDF ``<collision>`` elements against
            environment shapes or other links); the geometry is loaded only when there is one.
        bilateral: Bilateral constraints h(q) = 0 (loop closures, joint couplings); ``q0``
            must satisfy them to :data:`BILATERAL_TOLERANCE`.
        clearances: Revolute joints with radial clearance (the robot has their play joints,
            :func:`~ucontrol.model.joint_clearance.with_joint_clearance`).
        planar_axis: Unit normal of the plane the robot moves in, shape (3,): its frictional
            contacts are then planar (one tangent), else spatial (two); None: spatial.
        q0: Initial configuration of the links, shape (nq,).
        v0: Initial velocity of the links, shape (nv,).
        flexible: Flexible joints (their motor coordinates join the state), or None.
        motor_q0: Initial motor positions of the flexible joints, shape (nf,); default their
            link positions (unstretched springs).
        motor_v0: Initial motor velocities, shape (nf,); default their link velocities.
        joint_friction: Viscous and Coulomb friction in the joints (on the link coordinates,
            ``nv`` of them), or None: frictionless joints.
        duration: Default simulated time in [s].
        integrator: Default integrator settings.
        controller: Controller table (``type`` plus parameters); ``{"type": "zero"}`` if none.
        reference: Analytic reference table (``type`` plus parameters), checked when the scene
            is loaded, or None; used by
            :func:`ucontrol.analysis.convergence.run_convergence`.
        sensors: What the controller measures (noise, quantisation, velocity estimate,
            delay), or None: it reads the true state.
        actuators: Torque saturation and rate limits between controller and plant, or None.
        pushes: Velocity changes of the robot at given times (:class:`~ucontrol.scene.push.Push`).
        source: The TOML file the scene was loaded from, or None for a scene built in code;
            :func:`ucontrol.simulate` records it in the log (``scene_path``) for replays.
    """

    name: str
    robot: RobotModel
    contacts: tuple[PointContact, ...] = ()
    stops: tuple[JointStop, ...] = ()
    sphere_contacts: tuple[SphereSphereContact, ...] = ()
    collision_pairs: tuple[CollisionPair, ...] = ()
    bilateral: tuple[BilateralConstraint, ...] = ()
    clearances: tuple[ClearanceJoint, ...] = ()
    planar_axis: NDArray[np.float64] | None = None
    q0: NDArray[np.float64]
    v0: NDArray[np.float64]
    flexible: FlexibleJoints | None = None
    motor_q0: NDArray[np.float64] | None = None
    motor_v0: NDArray[np.float64] | None = None
    joint_friction: JointFriction | None = None
    duration: float = 1.0
    integrator: IntegratorSettings = field(default_factory=IntegratorSettings)
    controller: Mapping[str, Any] = field(default_factory=lambda: {"type": "zero"})
    reference: Mapping[str, Any] | None = None
    sensors: SensorSettings | None = None
    actuators: ActuatorSettings | None = None
    pushes: tuple[Push, ...] = ()
    source: Path | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "q0", self.robot.check_configuration("q0", self.q0))
        object.__setattr__(self, "v0", self.robot.check_velocity("v0", self.v0))
        object.__setattr__(self, "duration", as_positive("duration", self.duration))
        flexible = self.flexible
        if flexible is None:
            if self.motor_q0 is not None or self.motor_v0 is not None:
                raise SceneError("motor_q0 and motor_v0 need flexible joints")
        else:
            motor_q0 = flexible.link_positions(self.q0) if self.motor_q0 is None else self.motor_q0
            motor_v0 = self.v0[flexible.v_index] if self.motor_v0 is None else self.motor_v0
            object.__setattr__(self, "motor_q0", as_vector("motor_q0", motor_q0, flexible.nf))
            object.__setattr__(self, "motor_v0", as_vector("motor_v0", motor_v0, flexible.nf))
        if self.joint_friction is not None and self.joint_friction.nv != self.robot.nv:
            raise InvalidParameterError(
                "joint_friction",
                f"{self.joint_friction.nv} coordinates",
                f"{self.robot.nv} (the robot's nv)",
            )
        object.__setattr__(self, "contacts", tuple(self.contacts))
        object.__setattr__(self, "stops", tuple(self.stops))
        object.__setattr__(self, "sphere_contacts", tuple(self.sphere_contacts))
        object.__setattr__(self, "collision_pairs", tuple(self.collision_pairs))
        constraints = ConstraintSet(
            self.robot,
            self.contacts,
            self.stops,
            self.sphere_contacts,
            self.planar_axis,
            collision_pairs=self.collision_pairs,
            bilateral=tuple(self.bilateral),
            clearances=tuple(self.clearances),
        )
        object.__setattr__(self, "clearances", tuple(self.clearances))
        object.__setattr__(self, "bilateral", tuple(self.bilateral))
        if constraints.bilateral is not None:
            residual = constraints.bilateral.residuals(self.q0)
            worst = int(np.argmax(np.abs(residual)))
            if abs(residual[worst]) > BILATERAL_TOLERANCE:
                raise InvalidParameterError(
                    f"q0 (bilateral constraint {constraints.bilateral.names[worst]!r})",
                    self.q0.tolist(),
                    f"a configuration where it holds to {BILATERAL_TOLERANCE:g}, residual "
                    f"{residual[worst]:.3e}",
                )
        repeated = sorted({name for name in constraints.names if constraints.names.count(name) > 1})
        if repeated:
            raise SceneError(
                f"constraint names must be unique; {repeated} name several constraints (give "
                "each contact its own `name`)"
            )
        object.__setattr__(self, "_constraints", constraints)
        check_inertias(self.robot)
        _check_within_limits(self.robot, self.q0)
        _check_magnitude("v0", self.v0, MAX_VELOCITY)
        _check_magnitude("gravity", self.robot.gravity, MAX_GRAVITY)
        if self.sensors is not None:
            self.sensors.check_sizes(self.robot.nv + (0 if flexible is None else flexible.nf))
        if self.actuators is not None:
            self.actuators.check_sizes(self.robot.nu)
        check_mass_matrix(self.robot, self.q0)

    @property
    def constraints(self) -> ConstraintSet:
        """The unilateral constraints, contacts first then stops."""
        constraints: ConstraintSet = self.__dict__["_constraints"]
        return constraints

    def initial_state(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The plant's initial (q, v): the links', then the motors' with flexible joints."""
        if self.flexible is None:
            return self.q0, self.v0
        assert self.motor_q0 is not None and self.motor_v0 is not None
        return np.concatenate((self.q0, self.motor_q0)), np.concatenate((self.v0, self.motor_v0))


#: Largest residual of a bilateral constraint at q0, in [m] or [rad].
BILATERAL_TOLERANCE = 1e-6
#: Largest magnitude of an initial coordinate without joint limits, in [rad] or [m].
MAX_COORDINATE = 1e6


#: Largest magnitude of an initial velocity coordinate, in [rad/s] or [m/s].
MAX_VELOCITY = 1e6
#: Largest magnitude of a gravity component, in [m/s²] (1e5 g).
MAX_GRAVITY = 1e6


def _check_magnitude(name: str, values: NDArray[np.float64], bound: float) -> None:
    """Every entry of ``values`` at most ``bound`` in magnitude (larger ones overflow a step)."""
    worst = int(np.argmax(np.abs(values))) if values.size else 0
    if values.size and abs(values[worst]) > bound:
        raise InvalidParameterError(
            f"{name}[{worst}]", float(values[worst]), f"at most {bound:g} in magnitude"
        )


def _check_within_limits(robot: RobotModel, q0: NDArray[np.float64]) -> None:
    """``q0`` inside the URDF's position limits (where finite), and of a sane magnitude."""
    model = robot.model
    lower, upper = model.lowerPositionLimit, model.upperPositionLimit
    for j in range(1, model.njoints):
        joint = model.joints[j]
        for i in range(joint.idx_q, joint.idx_q + joint.nq):
            low, high = float(lower[i]), float(upper[i])
            bounded = np.isfinite(low) and np.isfinite(high) and low < high and high - low < 1e10
            if bounded and not low - 1e-9 <= q0[i] <= high + 1e-9:
                raise InvalidParameterError(
                    f"q0 of joint {model.names[j]!r}", float(q0[i]), f"within [{low:g}, {high:g}]"
                )
            if abs(q0[i]) > MAX_COORDINATE:
                raise InvalidParameterError(
                    f"q0 of joint {model.names[j]!r}", float(q0[i]), f"at most {MAX_COORDINATE:g}"
                )
