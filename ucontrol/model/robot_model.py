"""The robot: a Pinocchio model and its data, loaded from URDF or MJCF."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol._validation import as_positive, as_vector
from ucontrol.exceptions import (
    FrameNotFoundError,
    InvalidParameterError,
    JointNotFoundError,
    MJCFError,
    SDFError,
    URDFError,
)

Vector = NDArray[np.float64]

#: Largest nv for which the compiled symbolic terms (M, C, h, a frame's kinematics) of
#: :mod:`ucontrol.model.symbolic_model` beat Pinocchio's recursive algorithms: measured faster
#: at nv = 2 and slower at nv = 7, where the Christoffel terms, which grow as nv³ in the C
#: code, dominate (docs/benchmarks.md, sixth round). Here, not there, so that choosing a path
#: by it needs no casadi.
SMALL_ROBOT_MAX_NV = 3

#: The frame taken where several share a name, in order of preference.
_FRAME_PREFERENCE = (
    pin.FrameType.BODY,
    pin.FrameType.OP_FRAME,
    pin.FrameType.FIXED_JOINT,
    pin.FrameType.JOINT,
)


def frame_index(model: pin.Model, name: str) -> int:
    """Index of the existing frame ``name`` of ``model``, the link's where several share it.

    A joint named as its child link gives two frames of that name; Pinocchio's
    ``getFrameId`` then refuses to choose. The preference is :data:`_FRAME_PREFERENCE`.
    """
    for kind in _FRAME_PREFERENCE:
        if model.existFrame(name, kind):
            return int(model.getFrameId(name, kind))
    return int(model.getFrameId(name))


class RobotModel:
    r"""Rigid multibody dynamics of a robot described by a URDF or MJCF file.

    Wraps a Pinocchio model and one data buffer. The equations of motion read

    .. math:: M(q)\,\dot v + h(q, v) = S^T u + J^T \lambda,

    with :math:`h` the Coriolis, centrifugal and gravity terms. Configurations live on
    Pinocchio's configuration space (``nq`` may differ from ``nv``, e.g. with a free-flyer base);
    always advance them with :meth:`integrate`.

    Attributes:
        model: The Pinocchio model.
        data: The Pinocchio data buffer used by every computation of this object (created on
            first use: integrators and controllers bring their own).
        name: Robot name from the URDF or MJCF file.
        nq: Configuration size.
        nv: Velocity (tangent space) size.
        nu: Number of actuated velocity coordinates (``nv`` minus the free-flyer's 6 and the
            passive joints' coordinates).
        actuated: Indices in ``v`` of the actuated coordinates, increasing, shape (nu,): the
            rows of the identity that make the selection :math:`S`.
        passive_joints: Names of the joints declared passive (no input), in model order; a
            free-flyer base is never actuated and is not listed.
        urdf_path: The URDF file the model was loaded from (its visual geometry is drawn by
            :mod:`ucontrol.viz`), or None for a model built otherwise.
        mjcf_path: The MJCF file the model was loaded from, or None.
    """

    def __init__(
        self,
        model: pin.Model,
        *,
        floating_base: bool = False,
        urdf_path: Path | None = None,
        mjcf_path: Path | None = None,
        passive_joints: Iterable[str] = (),
    ) -> None:
        if urdf_path is not None and mjcf_path is not None:
            raise InvalidParameterError(
                "mjcf_path", str(mjcf_path), f"None with urdf_path given ({urdf_path})"
            )
        self.model = model
        self.urdf_path = urdf_path
        self.mjcf_path = mjcf_path
        self._data: pin.Data | None = None
        self.name = model.name
        self.floating_base = floating_base
        self.nq = model.nq
        self.nv = model.nv
        passive = set(passive_joints)
        for name in sorted(passive):
            self.joint_id(name)  # JointNotFoundError listing the joints that exist
        self.passive_joints = tuple(name for name in self.joint_names if name in passive)
        self.actuated = np.array(
            [
                joint.idx_v + k
                for joint, name in zip(model.joints[1:], self.joint_names, strict=True)
                if name not in passive and not (floating_base and joint.id == 1)
                for k in range(joint.nv)
            ],
            dtype=np.intp,
        )
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
            raise URDFError(str(path), _pinocchio_reason(error)) from error
        _set_gravity(model, gravity)
        return cls(model, floating_base=floating_base, urdf_path=path.resolve())

    @classmethod
    def from_mjcf(
        cls,
        path: str | Path,
        *,
        floating_base: bool = False,
        gravity: NDArray[np.float64] | None = None,
    ) -> RobotModel:
        """Load a robot from an MJCF (MuJoCo XML) file through Pinocchio's MJCF parser.

        Bodies become frames of their names (``<site>`` elements are not read). The file's
        ``<option gravity>`` is ignored: ``gravity`` sets it, as for a URDF. Equality
        constraints (``<equality>``) are refused rather than dropped: declare closed chains as
        the scene's ``[[bilateral]]`` entries. A floating base is the root body's
        ``<freejoint/>`` (Pinocchio 4.1's MJCF parser ignores the root joint it is given), so
        ``floating_base`` must say whether the file has one.

        Args:
            path: Path of the MJCF file.
            floating_base: The root body has a ``<freejoint/>`` (nq = nv + 1 extra).
            gravity: Gravity acceleration in the world frame in [m/s²], shape (3,);
                default (0, 0, -9.81).

        Raises:
            MJCFError: The file does not exist, is not an MJCF model Pinocchio can read, holds
                equality constraints, or its root joint disagrees with ``floating_base``.
        """
        path = Path(path)
        if not path.is_file():
            raise MJCFError(str(path), "file does not exist")
        try:
            model, constraints = pin.buildModelsFromMJCF(str(path), geometry_types=[])
        except (ValueError, RuntimeError) as error:
            raise MJCFError(str(path), _pinocchio_reason(error)) from error
        if len(constraints) > 0:
            raise MJCFError(
                str(path),
                f"{len(constraints)} equality constraint(s); declare closed chains as "
                "[[bilateral]] entries of the scene instead",
            )
        free = model.njoints > 1 and model.joints[1].shortname() == "JointModelFreeFlyer"
        if free != floating_base:
            raise MJCFError(
                str(path),
                f"floating_base is {floating_base} but the root body has "
                f"{'a' if free else 'no'} <freejoint/> (a floating base is declared in the file)",
            )
        _set_gravity(model, gravity)
        return cls(model, floating_base=floating_base, mjcf_path=path.resolve())

    @classmethod
    def from_sdf(cls, path: str | Path, **_: object) -> RobotModel:
        """Refuse an SDF file: ucontrol reads robots from URDF and MJCF only.

        The Pinocchio wheel on the package index is built without SDFormat
        (``pin.WITH_SDFORMAT`` is False); the message says whether the installed one is.

        Raises:
            SDFError: Always, naming the file and what to use instead.
        """
        if getattr(pin, "WITH_SDFORMAT", False):
            reason = "ucontrol does not read SDF yet (this Pinocchio could)"
        else:
            reason = (
                f"this Pinocchio ({pin.__version__}) has no SDF parser (built without "
                "SDFormat, pin.WITH_SDFORMAT is False)"
            )
        raise SDFError(str(path), f"{reason}; convert the robot to URDF or MJCF")

    def geometry_model(self, kind: pin.GeometryType) -> pin.GeometryModel:
        """The robot file's collision or visual shapes, attached to this model's frames.

        Args:
            kind: ``pin.GeometryType.COLLISION`` or ``pin.GeometryType.VISUAL``.

        Raises:
            InvalidParameterError: The model was not loaded from a file.
            RobotFileError: The shapes do not load (a missing mesh file); a
                :class:`URDFError` or :class:`MJCFError`.
        """
        if self.urdf_path is not None:
            path = self.urdf_path
            package_dirs = [str(folder) for folder in path.parents]  # package:// lookups
            try:
                return pin.buildGeomFromUrdf(self.model, str(path), kind, package_dirs=package_dirs)
            except (ValueError, RuntimeError) as error:
                raise URDFError(str(path), _pinocchio_reason(error)) from error
        if self.mjcf_path is not None:
            try:  # MJCF mesh paths are relative to the file (or its <compiler meshdir>)
                return pin.buildGeomFromMJCF(self.model, str(self.mjcf_path), kind)
            except (ValueError, RuntimeError) as error:
                raise MJCFError(str(self.mjcf_path), _pinocchio_reason(error)) from error
        raise InvalidParameterError("robot", self.name, "a robot loaded from a URDF or MJCF file")

    def with_model(self, model: pin.Model) -> RobotModel:
        """A robot of another model (a modified copy) with this one's file, base, passive joints."""
        return RobotModel(
            model,
            floating_base=self.floating_base,
            urdf_path=self.urdf_path,
            mjcf_path=self.mjcf_path,
            passive_joints=self.passive_joints,
        )

    def with_actuation(
        self, *, actuated: Iterable[str] | None = None, passive: Iterable[str] | None = None
    ) -> RobotModel:
        """A copy whose inputs act on the named joints only: :math:`S` selects their coordinates.

        Exactly one of ``actuated`` (every other joint is passive) or ``passive`` (every other
        joint is actuated) is given. A free-flyer base is never actuated: naming it in
        ``actuated`` is an error, naming it in ``passive`` changes nothing.

        Args:
            actuated: Names of the joints that receive an input.
            passive: Names of the joints that receive none.

        Raises:
            InvalidParameterError: Both or neither are given, or ``actuated`` names the
                free-flyer.
            JointNotFoundError: A name is not a joint of the model (the message lists them).
        """
        if (actuated is None) == (passive is None):
            raise InvalidParameterError(
                "actuated, passive",
                f"{actuated!r}, {passive!r}",
                "exactly one of the two lists of joint names",
            )
        if actuated is not None:
            names = [str(name) for name in actuated]
            for name in names:
                self.joint_id(name)
            if self.floating_base and self.joint_names[0] in names:
                raise InvalidParameterError(
                    "actuated", self.joint_names[0], "a joint other than the free-flyer base"
                )
            passive_names = [name for name in self.joint_names if name not in names]
        else:
            passive_names = [str(name) for name in passive or ()]
        return RobotModel(
            self.model,
            floating_base=self.floating_base,
            urdf_path=self.urdf_path,
            mjcf_path=self.mjcf_path,
            passive_joints=passive_names,
        )

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
        return self.with_model(model)

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
        return self.with_model(model)

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
        """Index of frame ``name``; raises :class:`FrameNotFoundError` listing existing ones.

        Where several frames share the name (a joint named as its child link), the link's
        (``BODY``) frame is taken, then an operational, a fixed-joint and a joint frame.
        """
        if not self.model.existFrame(name):
            raise FrameNotFoundError(name, self.frame_names)
        return frame_index(self.model, name)

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


def _pinocchio_reason(error: Exception) -> str:
    """The line of a Pinocchio parser's exception that says what is wrong.

    Pinocchio's C++ exceptions read ``From file: ... in function: ... at line: ...
    message: <reason>``; other exceptions are reduced to their first line.
    """
    lines = [line.strip() for line in str(error).splitlines()]
    for index, line in enumerate(lines):
        if line.startswith("message:"):
            following = [text for text in lines[index + 1 :] if text]
            return line.removeprefix("message:").strip() or next(iter(following), line)
    return next((line for line in lines if line), type(error).__name__)


def _set_gravity(model: pin.Model, gravity: NDArray[np.float64] | None) -> None:
    """Set the model's gravity in [m/s²] (Pinocchio's default (0, 0, -9.81) when None)."""
    if gravity is not None:
        model.gravity.linear = as_vector("gravity", gravity, 3)


def inertia_parameters(model: pin.Model) -> np.ndarray:
    """The ``inertia`` input of :class:`~ucontrol.model.symbolic_model.SymbolicModel` for ``model``.

    Per body (joint 1 to njoints - 1): mass [kg], centre of mass in the joint frame (3,) [m],
    rotational inertia about it (xx, xy, xz, yy, yz, zz) [kg m²]; shape (10 (njoints - 1),).
    """
    values = []
    for inertia in model.inertias[1:]:
        I_c = np.asarray(inertia.inertia)
        values += [inertia.mass, *inertia.lever, *I_c[0], *I_c[1, 1:], I_c[2, 2]]
    return np.asarray(values, dtype=float)
