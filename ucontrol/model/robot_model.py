"""The robot: a Pinocchio model and its data, loaded from URDF."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol._validation import as_positive, as_vector
from ucontrol.exceptions import (
    FrameNotFoundError,
    InvalidParameterError,
    JointNotFoundError,
    URDFError,
)

Vector = NDArray[np.float64]


class RobotModel:
    r"""Rigid multibody dynamics of a robot described by a URDF file.

    Wraps a Pinocchio model and one data buffer. The equations of motion read

    .. math:: M(q)\,\dot v + h(q, v) = S^T u + J^T \lambda,

    with :math:`h` the Coriolis, centrifugal and gravity terms. Configurations live on
    Pinocchio's configuration space (``nq`` may differ from ``nv``, e.g. with a free-flyer base);
    always advance them with :meth:`integrate`.

    Attributes:
        model: The Pinocchio model.
        data: The Pinocchio data buffer used by every computation of this object (created on
            first use: integrators and controllers bring their own).
        name: Robot name from the URDF.
        nq: Configuration size.
        nv: Velocity (tangent space) size.
        nu: Number of actuated velocity coordinates (``nv`` minus the free-flyer's 6).
        actuated: Indices in ``v`` of the actuated coordinates, shape (nu,).
        urdf_path: The URDF file the model was loaded from (its visual geometry is drawn by
            :mod:`ucontrol.viz`), or None for a model built otherwise.
    """

    def __init__(
        self, model: pin.Model, *, floating_base: bool = False, urdf_path: Path | None = None
    ) -> None:
        self.model = model
        self.urdf_path = urdf_path
        self._data: pin.Data | None = None
        self.name = model.name
        self.floating_base = floating_base
        self.nq = model.nq
        self.nv = model.nv
        first_actuated = 6 if floating_base else 0
        self.actuated = np.arange(first_actuated, model.nv)
        self.nu = self.actuated.size
        self._lower = np.tril_indices(model.nv, -1)

    @property
    def data(self) -> pin.Data:
        """The Pinocchio data buffer of this object's computations, created on first use.

        A Pinocchio ``Data`` holds several (nv, nv) and (6, nv) arrays per joint (512 MB at
        nv = 200): a run whose integrator and controller bring their own never builds this one.
        """
        if self._data is None:
            self._data = pin.Data(self.model)
        return self._data

    @classmethod
    def from_urdf(
        cls,
        path: str | Path,
        *,
        floating_base: bool = False,
        gravity: NDArray[np.float64] | None = None,
    ) -> RobotModel:
        """Load a robot from a URDF file.

        Args:
            path: Path of the URDF file.
            floating_base: Attach the root link with a free-flyer joint (nq = nv + 1 extra).
            gravity: Gravity acceleration in the world frame in [m/s²], shape (3,);
                default (0, 0, -9.81).

        Raises:
            URDFError: The file does not exist or is not a valid URDF.
        """
        path = Path(path)
        if not path.is_file():
            raise URDFError(str(path), "file does not exist")
        try:
            if floating_base:
                model = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
            else:
                model = pin.buildModelFromUrdf(str(path))
        except (ValueError, RuntimeError) as error:
            raise URDFError(str(path), str(error).splitlines()[0]) from error
        if gravity is not None:
            model.gravity.linear = as_vector("gravity", gravity, 3)
        return cls(model, floating_base=floating_base, urdf_path=path.resolve())

    def with_scaled_inertia(self, factor: float) -> RobotModel:
        """A copy whose link masses and rotational inertias are multiplied by ``factor``.

        The kinematics and the centres of mass are unchanged. Used to give a controller a
        wrong model of the plant (robustness studies).

        Args:
            factor: Scale of every mass and inertia, > 0 (1.2: 20 % heavier).
        """
        factor = as_positive("factor", factor)
        model = self.model.copy()
        for i, inertia in enumerate(model.inertias):
            model.inertias[i] = pin.Inertia(
                inertia.mass * factor, inertia.lever, inertia.inertia * factor
            )
        return RobotModel(model, floating_base=self.floating_base, urdf_path=self.urdf_path)

    def with_armature(self, armature: Vector) -> RobotModel:
        """A copy with rotor inertias added to the diagonal of M(q).

        The rigid limit of flexible joints (:class:`~ucontrol.model.FlexibleJoints`): each motor
        rigidly attached to its link adds its inertia B to the joint's diagonal entry.

        Args:
            armature: Inertia per velocity coordinate in [kg m²] (or [kg]), shape (nv,), >= 0.
        """
        armature = as_vector("armature", armature, self.nv)
        if np.any(armature < 0.0):
            raise InvalidParameterError("armature", armature.tolist(), ">= 0")
        model = self.model.copy()
        model.armature = model.armature + armature
        return RobotModel(model, floating_base=self.floating_base, urdf_path=self.urdf_path)

    @property
    def gravity(self) -> Vector:
        """Gravity acceleration in the world frame in [m/s²], shape (3,)."""
        return np.array(self.model.gravity.linear)

    @property
    def frame_names(self) -> list[str]:
        """Names of every frame of the model."""
        return [frame.name for frame in self.model.frames]

    @property
    def joint_names(self) -> list[str]:
        """Names of the joints, the universe excluded."""
        return list(self.model.names)[1:]

    def frame_id(self, name: str) -> int:
        """Index of frame ``name``; raises :class:`FrameNotFoundError` listing existing ones."""
        if not self.model.existFrame(name):
            raise FrameNotFoundError(name, self.frame_names)
        return int(self.model.getFrameId(name))

    def joint_id(self, name: str) -> int:
        """Index of joint ``name``; raises :class:`JointNotFoundError` listing existing ones."""
        if not self.model.existJointName(name):
            raise JointNotFoundError(name, self.joint_names)
        return int(self.model.getJointId(name))

    def neutral(self) -> Vector:
        """Neutral configuration, shape (nq,)."""
        return pin.neutral(self.model)

    def check_configuration(self, name: str, q: object) -> Vector:
        """Return ``q`` as a configuration vector of shape (nq,) or raise a typed error."""
        return as_vector(name, q, self.nq)

    def check_velocity(self, name: str, v: object) -> Vector:
        """Return ``v`` as a velocity vector of shape (nv,) or raise a typed error."""
        return as_vector(name, v, self.nv)

    def integrate(self, q: Vector, dq: Vector) -> Vector:
        """Configuration reached from ``q`` (nq,) along the tangent displacement ``dq`` (nv,)."""
        return pin.integrate(self.model, q, dq)

    def mass_matrix(self, q: Vector) -> Vector:
        """Joint-space inertia matrix M(q) in [kg m²] (mixed units), shape (nv, nv)."""
        M = pin.crba(self.model, self.data, q).copy()
        lower = self._lower
        M[lower] = M.T[lower]  # crba fills the upper triangle
        return M

    def nonlinear_effects(self, q: Vector, v: Vector) -> Vector:
        """Coriolis, centrifugal and gravity generalized forces h(q, v), shape (nv,)."""
        return pin.nonLinearEffects(self.model, self.data, q, v).copy()

    def gravity_torque(self, q: Vector) -> Vector:
        """Generalized gravity forces g(q), shape (nv,)."""
        return pin.computeGeneralizedGravity(self.model, self.data, q).copy()

    def frame_position(self, q: Vector, frame: str) -> Vector:
        """Position of frame ``frame`` in the world in [m], shape (3,)."""
        frame_id = self.frame_id(frame)
        pin.framesForwardKinematics(self.model, self.data, q)
        return self.data.oMf[frame_id].translation.copy()

    def frame_path(self, configurations: Vector, frame: str) -> Vector:
        """Positions of frame ``frame`` in the world along ``configurations`` (N, nq), in [m].

        Returns:
            Shape (N, 3). Uses a data buffer of its own.
        """
        frame_id = self.frame_id(frame)
        data = pin.Data(self.model)
        path = np.empty((len(configurations), 3))
        for k, q in enumerate(configurations):
            pin.framesForwardKinematics(self.model, data, q)
            path[k] = data.oMf[frame_id].translation
        return path

    def frame_jacobian(self, q: Vector, frame: str) -> Vector:
        """Jacobian of frame ``frame`` in LOCAL_WORLD_ALIGNED, shape (6, nv).

        Rows 0–2 map ``v`` to the linear velocity of the frame origin in world axes [m/s],
        rows 3–5 to its angular velocity [rad/s].
        """
        frame_id = self.frame_id(frame)
        return pin.computeFrameJacobian(
            self.model, self.data, q, frame_id, pin.LOCAL_WORLD_ALIGNED
        ).copy()

    def energy(self, q: Vector, v: Vector) -> tuple[float, float]:
        """Kinetic and gravitational potential energy in [J] at (q, v)."""
        kinetic = pin.computeKineticEnergy(self.model, self.data, q, v)
        potential = pin.computePotentialEnergy(self.model, self.data, q)
        return float(kinetic), float(potential)
