r"""Bilateral constraints :math:`h(q) = 0`: loop closures between two frames, joint couplings.

The book's plant :math:`M \ddot q + F = \nabla f\,\lambda_u + \nabla h\,\lambda_b` has, beside
the unilateral :math:`f(q) \ge 0`, bilateral constraints whose multipliers are free in sign.

- :class:`FrameClosure` ``kind = "point"`` (Pinocchio's ``CONTACT_3D``): the origins of two
  frames coincide, :math:`h = p_1(q) - p_2(q) \in \mathbb R^3` (world coordinates), row
  :math:`J_{lin}(F_1) - J_{lin}(F_2)` in LOCAL_WORLD_ALIGNED.
- :class:`FrameClosure` ``kind = "weld"`` (``CONTACT_6D``): the two frames coincide,
  :math:`h = \log_6({}^2M_1) \in \mathbb R^6` (frame 1 seen from frame 2, linear then
  angular), rows :math:`\mathrm{Ad}_{{}^2M_1} J(F_1) - J(F_2)` with LOCAL frame Jacobians: the
  velocity of frame 1 relative to frame 2, the derivative of :math:`h` where it vanishes.
- :class:`JointCoupling`: :math:`h = q_a - r\,q_b - c` for one-degree-of-freedom joints (a
  gear or a belt of ratio r).

:class:`BilateralSet` stacks them; a planar mechanism closed by a point closure has a zero
row (the out-of-plane one): the rows may be dependent, the solver copes (redundant closures).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol._validation import as_float
from ucontrol.exceptions import InvalidParameterError
from ucontrol.model.robot_model import RobotModel

Vector = NDArray[np.float64]
#: Closure kinds of :class:`FrameClosure` and their number of rows.
CLOSURE_ROWS = {"point": 3, "weld": 6}
_LWA = pin.LOCAL_WORLD_ALIGNED


@dataclass(frozen=True, kw_only=True)
class FrameClosure:
    """Frames ``frame`` and ``other_frame`` held together (a loop closure).

    Attributes:
        frame: Name of the first frame.
        other_frame: Name of the second frame (``"universe"``: the world).
        kind: ``"point"`` (their origins coincide, 3 rows) or ``"weld"`` (their poses
            coincide, 6 rows).
        name: Label in errors; default ``"<frame>=<other_frame>"``.
    """

    frame: str
    other_frame: str
    kind: str = "point"
    name: str = ""

    def __post_init__(self) -> None:
        if self.kind not in CLOSURE_ROWS:
            raise InvalidParameterError("kind", self.kind, f"one of {tuple(CLOSURE_ROWS)}")
        if self.frame == self.other_frame:
            raise InvalidParameterError("other_frame", self.other_frame, "a frame other than frame")
        if not self.name:
            object.__setattr__(self, "name", f"{self.frame}={self.other_frame}")

    @property
    def rows(self) -> int:
        """Number of scalar constraints."""
        return CLOSURE_ROWS[self.kind]


@dataclass(frozen=True, kw_only=True)
class JointCoupling:
    """``q[joint] = ratio * q[other_joint] + offset`` for two one-degree-of-freedom joints.

    Attributes:
        joint: Name of the driven joint.
        other_joint: Name of the driving joint.
        ratio: Ratio r (dimensionless for joints of the same kind).
        offset: Offset c in [rad] or [m].
        name: Label in errors; default ``"<joint>~<other_joint>"``.
    """

    joint: str
    other_joint: str
    ratio: float = 1.0
    offset: float = 0.0
    name: str = ""

    def __post_init__(self) -> None:
        if self.joint == self.other_joint:
            raise InvalidParameterError("other_joint", self.other_joint, "a joint other than joint")
        object.__setattr__(self, "ratio", as_float("ratio", self.ratio))
        object.__setattr__(self, "offset", as_float("offset", self.offset))
        if not self.name:
            object.__setattr__(self, "name", f"{self.joint}~{self.other_joint}")

    @property
    def rows(self) -> int:
        """Number of scalar constraints."""
        return 1


BilateralConstraint = FrameClosure | JointCoupling


class BilateralSet:
    """The bilateral constraints of a scene as one stack of rows.

    Args:
        robot: The robot.
        constraints: Frame closures and joint couplings, in order.

    Attributes:
        constraints: The constraints.
        names: One label per row (``"<name>[k]"``).
        size: Number of rows m.

    Raises:
        FrameNotFoundError: A closure names a frame the robot does not have.
        JointNotFoundError: A coupling names a joint the robot does not have.
        InvalidParameterError: A coupled joint has more than one degree of freedom.
    """

    def __init__(self, robot: RobotModel, constraints: Sequence[BilateralConstraint]) -> None:
        self.robot = robot
        self.constraints = tuple(constraints)
        self._terms: list[tuple[str, int, int, float, float]] = []
        self._coupling_v: dict[int, tuple[int, int]] = {}
        names: list[str] = []
        for constraint in self.constraints:
            if isinstance(constraint, FrameClosure):
                self._terms.append(
                    (
                        constraint.kind,
                        robot.frame_id(constraint.frame),
                        robot.frame_id(constraint.other_frame),
                        0.0,
                        0.0,
                    )
                )
            else:
                first, second = (
                    robot.model.joints[robot.joint_id(name)]
                    for name in (constraint.joint, constraint.other_joint)
                )
                for joint, name in ((first, constraint.joint), (second, constraint.other_joint)):
                    if joint.nq != 1 or joint.nv != 1:
                        raise InvalidParameterError(
                            "joint", name, "a revolute or prismatic joint with nq = nv = 1"
                        )
                # Positions and velocities are indexed apart (a free-flyer before them).
                self._coupling_v[len(self._terms)] = (first.idx_v, second.idx_v)
                self._terms.append(
                    ("coupling", first.idx_q, second.idx_q, constraint.ratio, constraint.offset)
                )
            names += [f"{constraint.name}[{k}]" for k in range(constraint.rows)]
        self.names = names
        self.size = len(names)

    def residual(self, data: pin.Data, q: Vector) -> Vector:
        """:math:`h(q)`, shape (m,), in [m], [rad] (weld: log6, linear then angular).

        ``data`` must hold the frame placements at q (``pin.framesForwardKinematics``).
        """
        h = np.empty(self.size)
        start = 0
        for kind, first, second, ratio, offset in self._terms:
            if kind == "point":
                h[start : start + 3] = data.oMf[first].translation - data.oMf[second].translation
                start += 3
            elif kind == "weld":
                relative = data.oMf[second].actInv(data.oMf[first])
                h[start : start + 6] = pin.log6(relative).vector
                start += 6
            else:
                h[start] = q[first] - ratio * q[second] - offset
                start += 1
        return h

    def jacobian(self, data: pin.Data) -> Vector:
        r"""Rows :math:`\partial h / \partial q` (velocity form), shape (m, nv).

        ``data`` must hold joint Jacobians and frame placements (``pin.computeAllTerms`` then
        ``pin.updateFramePlacements``).
        """
        model = self.robot.model
        J = np.zeros((self.size, self.robot.nv))
        start = 0
        for index, (kind, first, second, ratio, _) in enumerate(self._terms):
            if kind == "point":
                J[start : start + 3] = (
                    pin.getFrameJacobian(model, data, first, _LWA)[:3]
                    - pin.getFrameJacobian(model, data, second, _LWA)[:3]
                )
                start += 3
            elif kind == "weld":
                relative = data.oMf[second].actInv(data.oMf[first])  # 2M1
                J[start : start + 6] = relative.action @ pin.getFrameJacobian(
                    model, data, first, pin.LOCAL
                ) - pin.getFrameJacobian(model, data, second, pin.LOCAL)
                start += 6
            else:
                v_first, v_second = self._coupling_v[index]
                J[start, v_first] += 1.0
                J[start, v_second] -= ratio
                start += 1
        return J

    def drift(self, data: pin.Data) -> Vector:
        r""":math:`\dot J_b v`, the rows' accelerations at zero joint acceleration, shape (m,).

        In the units of the rows' rates ([m/s²], [rad/s²]). A point closure gives the difference
        of the frames' classical accelerations (LOCAL_WORLD_ALIGNED); a weld the derivative of
        the relative velocity :math:`\nu_r = \mathrm{Ad}_{{}^2M_1} \nu_1 - \nu_2` (LOCAL
        twists), :math:`\mathrm{Ad}_{{}^2M_1} (\dot\nu_1 + \nu_{1/2} \times \nu_1) -
        \dot\nu_2` with :math:`\nu_{1/2} = \nu_1 - \mathrm{Ad}_{{}^1M_2} \nu_2` the velocity
        of frame 1 relative to frame 2 in frame 1; a coupling 0. ``data`` must hold
        ``pin.forwardKinematics(model, data, q, v, 0)`` and the frame placements.
        """
        model = self.robot.model
        drift = np.zeros(self.size)
        start = 0
        for kind, first, second, _, _ in self._terms:
            if kind == "point":
                drift[start : start + 3] = (
                    pin.getFrameClassicalAcceleration(model, data, first, _LWA).linear
                    - pin.getFrameClassicalAcceleration(model, data, second, _LWA).linear
                )
                start += 3
            elif kind == "weld":
                relative = data.oMf[second].actInv(data.oMf[first])  # 2M1
                nu1 = pin.getFrameVelocity(model, data, first, pin.LOCAL)
                nu2 = pin.getFrameVelocity(model, data, second, pin.LOCAL)
                nu12 = nu1 - relative.actInv(nu2)  # frame 1 relative to frame 2, in frame 1
                rate1 = pin.getFrameAcceleration(model, data, first, pin.LOCAL) + nu12.cross(nu1)
                rate2 = pin.getFrameAcceleration(model, data, second, pin.LOCAL)
                drift[start : start + 6] = relative.act(rate1).vector - rate2.vector
                start += 6
            else:
                start += 1
        return drift

    def residuals(self, q: Vector) -> Vector:
        """:math:`h(q)`, shape (m,); runs forward kinematics on the robot's data."""
        data = self.robot.data
        pin.framesForwardKinematics(self.robot.model, data, q)
        return self.residual(data, q)
