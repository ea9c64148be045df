r"""The heel-strike section of a planar biped under virtual constraints, as a chart.

A state just after a heel strike has its new stance foot on the ground and at rest. Its
coordinates for :func:`~ucontrol.analysis.gait.find_gait` are those the law sees, in the
stance/swing labelling of :class:`~ucontrol.control.hzd_controller.HZDController`:

.. math:: z = (\varphi, q_a, \dot\varphi, \dot q_a) \in \mathbb{R}^{10},
          \quad q_a = (\text{stance hip}, \text{stance knee}, \text{swing hip},
          \text{swing knee}),

with :math:`\varphi` the torso's pitch. The base's position and velocity follow from the stance
foot, placed at the origin (x is irrelevant on flat ground) and at rest. Relabelling the legs
in :meth:`BipedSection.from_state` makes the map from one step to the next a map of one
section, whatever foot is down. The chart keeps a direction the section does not have (the
swing foot's height at the strike): its multiplier is 0 (``drop_trivial = 1``).
:func:`find_biped_gait` puts the stance flow, this chart and
:func:`~ucontrol.analysis.gait.find_gait` together.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol._validation import as_vector
from ucontrol.analysis.gait import Gait, find_gait
from ucontrol.analysis.stance_flow import StanceFlow
from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.control.hzd_controller import OUTPUTS, HZDController
from ucontrol.exceptions import InvalidParameterError

Vector = NDArray[np.float64]
#: Size of the chart's coordinates.
SIZE = 2 * (OUTPUTS + 1)
#: Tolerances (rtol = atol) of the closed loop's strides in :func:`find_biped_gait`.
STRIDE_TOLERANCE = 1e-10
#: Longest stride in [s] of :func:`find_biped_gait` (RABBIT's steps last about 0.6 s).
MAX_STRIDE = 2.0


class BipedSection:
    """Chart of the heel-strike section of a planar biped (module docstring).

    Args:
        law: The walking law (its legs and their joints).
        flow: The biped's stance flow (which foot is down after a strike).
        base: Names of the base's x, z (prismatic) and pitch (revolute) joints.

    Raises:
        JointNotFoundError: A base joint the robot lacks.
        InvalidParameterError: The robot has other joints than the base's and the legs'.
    """

    def __init__(
        self,
        law: HZDController,
        flow: StanceFlow,
        *,
        base: tuple[str, str, str] = ("x", "z", "pitch"),
    ) -> None:
        robot = law.robot
        self._base = [int(robot.model.joints[robot.joint_id(name)].idx_v) for name in base]
        legs = [law.output_indices(0)[1], law.output_indices(1)[1]]
        if sorted(self._base + legs[0]) != list(range(robot.nv)):
            raise InvalidParameterError(
                "robot", robot.name, f"a planar base {list(base)} and two legs, nothing else"
            )
        self.law = law
        self.flow = flow
        self.robot = robot
        self._legs = legs
        self._data = pin.Data(robot.model)

    def to_state(self, z: Vector) -> tuple[Vector, Vector]:
        """The post-strike state (q (nq,), v (nv,)) of chart coordinates z (10,), left foot down.

        The first leg of the law is the stance leg; its foot is at the origin and at rest.
        """
        z = as_vector("z", z, SIZE)
        model, data = self.robot.model, self._data
        x, height, pitch = self._base
        stance_leg = self.law.legs[0]
        q, v = np.zeros(self.robot.nq), np.zeros(self.robot.nv)
        q[pitch], q[self._legs[0]] = z[0], z[1 : OUTPUTS + 1]
        v[pitch], v[self._legs[0]] = z[OUTPUTS + 1], z[OUTPUTS + 2 :]
        frame = self.robot.frame_id(stance_leg.foot)
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        foot = data.oMf[frame].translation
        q[x], q[height] = -foot[0], -foot[2]
        J = pin.getFrameJacobian(model, data, frame, pin.LOCAL_WORLD_ALIGNED)[[0, 2]]
        v[[x, height]] = np.linalg.solve(J[:, [x, height]], -J @ v)
        return q, v

    def from_state(self, q: Vector, v: Vector) -> Vector:
        """Chart coordinates (10,) of a post-strike state, the foot down as the stance leg."""
        leg = self.law.leg_of(self.flow.stance_of(q, v))
        index = self._legs[leg]
        pitch = self._base[2]
        return np.concatenate(([q[pitch]], q[index], [v[pitch]], v[index]))


def find_biped_gait(
    law: HZDController,
    constraints: ConstraintSet,
    q0: Vector,
    v0: Vector,
    *,
    tol: float = 1e-9,
) -> tuple[BipedSection, Gait]:
    """The period-one gait of a biped under its law, by Newton on the stride map at heel strike.

    The strides are the event-driven closed loop's (:class:`StanceFlow` with ``law``,
    :data:`STRIDE_TOLERANCE`, :data:`MAX_STRIDE`) on the chart of :class:`BipedSection`;
    Newton (:func:`~ucontrol.analysis.gait.find_gait`, the swing foot's trivial multiplier
    dropped) starts from the post-strike state (q0, v0).

    Args:
        law: The walking law.
        constraints: The biped's feet (a scene's constraints).
        q0: Post-strike configuration to start from, shape (nq,).
        v0: Post-strike velocity, shape (nv,).
        tol: Newton's tolerance on the residual :math:`P(z) - z`.

    Returns:
        The section (its :attr:`BipedSection.flow` the stance flow) and the gait.

    Raises:
        SolverError: Newton did not converge (:func:`~ucontrol.analysis.gait.find_gait`).
        StrideError: A stride failed (:meth:`StanceFlow.stride`).
    """
    flow = StanceFlow(
        constraints,
        law=law,
        rtol=STRIDE_TOLERANCE,
        atol=STRIDE_TOLERANCE,
        max_duration=MAX_STRIDE,
    )
    section = BipedSection(law, flow)
    z0 = section.from_state(q0, v0)
    gait = find_gait(flow, section.to_state, section.from_state, z0, drop_trivial=1, tol=tol)
    return section, gait
