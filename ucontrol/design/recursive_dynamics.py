r"""Recursive Newton–Euler dynamics of a fixed-base robot as compact casadi expressions.

:class:`ucontrol.model.symbolic_model.SymbolicModel` builds :math:`M(q)` from the bodies'
Jacobians and :math:`C(q, v)` from derivatives of :math:`M`: simple and exact, but for a
nine-joint arm :math:`C(q, v)v + g(q)` has about 1e5 expression nodes, which the optimal-control
problem evaluates with its derivatives at every Runge–Kutta stage. The recursive Newton–Euler
algorithm (Featherstone, *Rigid Body Dynamics Algorithms*, Springer 2008, ch. 5; Pinocchio's
``rnea``) gives :math:`\tau = M(q)\dot v + h(q, v)` in :math:`O(n)` operations:

.. math::

    v_i = {}^iX_{\lambda(i)} v_{\lambda(i)} + S_i \dot q_i, \quad
    a_i = {}^iX_{\lambda(i)} a_{\lambda(i)} + S_i \ddot q_i + v_i \times S_i \dot q_i, \quad
    f_i = I_i a_i + v_i \times^* I_i v_i,

with :math:`a_0 = -g` (gravity), then :math:`\tau_i = S_i^T f_i` and
:math:`f_{\lambda(i)} \mathrel{+}= {}^{\lambda(i)}X_i^* f_i` from the leaves to the root. The
columns of :math:`M` are :math:`\tau(q, 0, e_j) - g(q)`. Spatial vectors are (linear, angular)
pairs of 3-vectors at each joint frame's origin, in that frame.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from ucontrol.model.robot_model import RobotModel
from ucontrol.model.symbolic_model import _joint_axis, _rotation


class RecursiveDynamics:
    """``h(q, v) = C(q, v) v + g(q)`` and ``M(q)`` by the recursive Newton–Euler algorithm.

    Args:
        robot: A fixed-base robot whose joints are all revolute or prismatic (nq = nv).

    Attributes:
        nv: Number of joint coordinates.
        nonlinear_effects: ``(q (nv,), v (nv,)) -> h (nv,)`` in [N m] (or [N]).
        mass_matrix: ``(q (nv,)) -> M (nv, nv)`` in [kg m²] (mixed units).
    """

    def __init__(self, robot: RobotModel) -> None:
        model = robot.model
        self.nv = nv = model.nv
        self._model = model
        q, v = ca.SX.sym("q", nv), ca.SX.sym("v", nv)
        self._joints = []
        for i in range(1, model.njoints):
            kind, axis = _joint_axis(model, i)
            placement = model.jointPlacements[i]
            index = model.joints[i].idx_v
            rotation: Any = ca.DM(placement.rotation)
            translation: Any = ca.DM(placement.translation)
            if kind == "revolute":
                rotation = rotation @ _rotation(axis, q[index])
            else:
                translation = translation + rotation @ (ca.DM(axis) * q[index])
            self._joints.append((kind, ca.DM(axis), index, rotation, translation))
        zero = ca.SX.zeros(nv)
        h = self._rnea(v, zero, gravity=True)
        g = self._rnea(zero, zero, gravity=True)
        columns = [self._rnea(zero, ca.SX(ca.DM.eye(nv)[:, j]), gravity=False) for j in range(nv)]
        self.nonlinear_effects = ca.Function("h", [q, v], [h], ["q", "v"], ["h"])
        self.mass_matrix = ca.Function("M", [q], [ca.horzcat(*columns)], ["q"], ["M"])
        self.gravity = ca.Function("g", [q], [g], ["q"], ["g"])

    def _rnea(self, v: Any, a: Any, *, gravity: bool) -> Any:
        """Joint torques for velocities ``v`` and accelerations ``a`` (expressions, (nv,))."""
        model = self._model
        n = model.njoints
        gravity_linear = ca.DM(np.asarray(model.gravity.linear)) if gravity else ca.DM.zeros(3)
        velocity: list[tuple[Any, Any]] = [(ca.SX.zeros(3), ca.SX.zeros(3))]
        acceleration: list[tuple[Any, Any]] = [(-gravity_linear, ca.SX.zeros(3))]
        forces: list[list[Any]] = [[ca.SX.zeros(3), ca.SX.zeros(3)] for _ in range(n)]
        for i in range(1, n):
            kind, axis, index, R, p = self._joints[i - 1]
            parent = model.parents[i]
            lin_p, ang_p = velocity[parent]
            acc_lin_p, acc_ang_p = acceleration[parent]
            # motion from the parent's frame into joint i's: R^T (v + ω × p), R^T ω
            lin = R.T @ (lin_p + ca.cross(ang_p, p))
            ang = R.T @ ang_p
            acc_lin = R.T @ (acc_lin_p + ca.cross(acc_ang_p, p))
            acc_ang = R.T @ acc_ang_p
            s_lin, s_ang = (ca.DM.zeros(3), axis) if kind == "revolute" else (axis, ca.DM.zeros(3))
            qd, qdd = v[index], a[index]
            lin, ang = lin + s_lin * qd, ang + s_ang * qd
            # a += S q̈ + v × S q̇, (v, ω) × (m_v, m_ω) = (ω × m_v + v × m_ω, ω × m_ω)
            acc_lin = acc_lin + s_lin * qdd + ca.cross(ang, s_lin * qd) + ca.cross(lin, s_ang * qd)
            acc_ang = acc_ang + s_ang * qdd + ca.cross(ang, s_ang * qd)
            velocity.append((lin, ang))
            acceleration.append((acc_lin, acc_ang))
            inertia = model.inertias[i]
            mass, c = inertia.mass, ca.DM(inertia.lever)
            I_c = ca.DM(inertia.inertia)  # [kg m²] about the centre of mass
            # I a and I v: linear m (a_v + a_ω × c), angular I_c a_ω + c × linear
            f_lin = mass * (acc_lin + ca.cross(acc_ang, c))
            f_ang = I_c @ acc_ang + ca.cross(c, f_lin)
            h_lin = mass * (lin + ca.cross(ang, c))
            h_ang = I_c @ ang + ca.cross(c, h_lin)
            # v ×* (h_lin, h_ang) = (ω × h_lin, ω × h_ang + v × h_lin)
            forces[i][0] = forces[i][0] + f_lin + ca.cross(ang, h_lin)
            forces[i][1] = forces[i][1] + f_ang + ca.cross(ang, h_ang) + ca.cross(lin, h_lin)
        tau = [ca.SX(0)] * self.nv
        for i in range(n - 1, 0, -1):
            kind, axis, index, R, p = self._joints[i - 1]
            f_lin, f_ang = forces[i]
            tau[index] = ca.dot(axis, f_ang if kind == "revolute" else f_lin)
            parent = model.parents[i]
            # force into the parent's frame: R f, R n + p × R f
            parent_lin = R @ f_lin
            forces[parent][0] = forces[parent][0] + parent_lin
            forces[parent][1] = forces[parent][1] + R @ f_ang + ca.cross(p, parent_lin)
        return ca.vertcat(*tau)
