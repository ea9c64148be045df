r"""The free part of a Moreau–Jean step in one compiled call.

Before its contact problem, a Moreau–Jean step of a robot whose joints are all vector spaces
(nq = nv: revolute and prismatic joints) computes, in numpy and LAPACK, a dozen small array
operations of about 0.5 µs each (:mod:`ucontrol.integrators.moreau_jean`). With every
generalized force of the step linear in the state, they are written here as one casadi Function,
compiled to C (:class:`~ucontrol.model.compiled_function.CompiledFunction`):

.. math::

    W = W_0 + \begin{pmatrix} M(q_k) & 0 \\ 0 & 0 \end{pmatrix}, \quad
    f = \tau - \begin{pmatrix} h(q_k, v_k) \\ 0 \end{pmatrix} - K_q q_k - F v_k, \quad
    v^{free} = v_k + W^{-1} (\mathrm{h} f),

    q^{free} = q_k + \mathrm{h}\big((1 - \theta) v_k + \theta v^{free}\big), \quad
    \tilde g = g_k + \gamma \mathrm{h}\, u_k, \quad
    W^{-1} J^T, \quad J W^{-1} J^T,

with the constant matrices of the flexible joints (Spong's model, docs/flexible.md) and of the
viscous joint friction: :math:`W_0 = \mathrm{h}\theta (C_v + D) + \mathrm{h}^2\theta^2 K_q +
\mathrm{diag}(0, B)`, :math:`F = C_v + \mathrm{h}\theta K_q + D` (:math:`K_q`, :math:`C_v` the
springs' stiffness and damping matrices on the extended coordinates, B the motor inertias, D
the viscous friction on the links; all zero on a rigid robot without joint friction). J are the
normal rows of every constraint (:class:`~ucontrol.contact.compiled_rows.ConstraintRows`), zero
on the motors. W is factored by a Cholesky decomposition written out in the expression; the
results equal the numpy and Pinocchio path to round-off.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ucontrol.model.flexible_joints import FlexibleJoints
from ucontrol.plant import PlantEvaluation

Vector = NDArray[np.float64]


class CompiledFreeStep:
    """The free velocity, free configuration, predicted gaps and Delassus terms of a step.

    Args:
        data_M: The Pinocchio data's mass matrix buffer (upper triangle read), shape (nv, nv).
        data_nle: The Pinocchio data's nonlinear-effects buffer, shape (nv,).
        n: Number of constraints.
        dt: Step h in [s].
        theta: θ of the position update.
        horizon: γ h, the active-set prediction horizon in [s].
        flexible: The flexible joints, or None.
        viscous: Viscous joint friction D on the links, shape (nv,), or None.

    Attributes:
        compiled: Whether calls run compiled C (else the caller should not use it).
    """

    def __init__(
        self,
        data_M: Vector,
        data_nle: Vector,
        n: int,
        *,
        dt: float,
        theta: float,
        horizon: float,
        flexible: FlexibleJoints | None,
        viscous: Vector | None,
    ) -> None:
        import casadi as ca  # imported only for the steps that use it

        from ucontrol.model.compiled_function import CompiledFunction

        nv = data_nle.size
        size = nv if flexible is None else nv + flexible.nf
        W0, Kq, F = _constant_terms(nv, size, dt, theta, flexible, viscous)
        q, v, tau = ca.SX.sym("q", size), ca.SX.sym("v", size), ca.SX.sym("tau", size)
        M_upper, nle = ca.SX.sym("M", nv, nv), ca.SX.sym("nle", nv)
        rows, gap, velocity = ca.SX.sym("J", n, nv), ca.SX.sym("gap", n), ca.SX.sym("u", n)
        W0_s, Kq_s, F_s = (ca.SX.sym(name, size, size) for name in ("W0", "Kq", "F"))
        scalars = ca.SX.sym("scalars", 3)  # h, θ, γh
        h, th, gh = scalars[0], scalars[1], scalars[2]
        M = ca.triu(M_upper) + ca.triu(M_upper, False).T
        W = W0_s + ca.diagcat(M, ca.SX.zeros(size - nv, size - nv))
        force = tau - ca.vertcat(nle, ca.SX.zeros(size - nv)) - Kq_s @ q - F_s @ v
        J = ca.horzcat(rows, ca.SX.zeros(n, size - nv))
        factor = _cholesky(W)
        v_free = v + _cholesky_solve(factor, h * force)
        Winv_Jt = _cholesky_solve(factor, J.T)
        outputs = ca.vertcat(
            v_free,
            q + h * ((1.0 - th) * v + th * v_free),
            gap + gh * velocity,
            ca.vec(Winv_Jt),
            ca.vec(J @ Winv_Jt),
        )
        inputs = [q, v, tau, M_upper, nle, rows, gap, velocity, W0_s, Kq_s, F_s, scalars]
        self.function = CompiledFunction(ca.Function("free_step", inputs, [outputs]))
        self.compiled = self.function.compiled
        if self.compiled:
            self.function.bind_input(3, data_M)
            self.function.bind_input(4, data_nle)
        for i, value in ((8, W0), (9, Kq), (10, F)):
            self.function.input_view(i)[...] = value
        self.function.input_buffer(11)[:] = (dt, theta, horizon)
        self._sizes = (size, n)
        self._split = np.cumsum([size, size, n, size * n])
        self._last: Vector | None = None  # the last call's outputs

    def __call__(self, state: PlantEvaluation, tau: Vector) -> tuple[Vector, Vector, Vector]:
        """:math:`v^{free}`, :math:`q^{free}` (each (N,)) and the predicted gaps (n,).

        ``state`` must carry its normal rows (:attr:`PlantEvaluation.normal_rows`). The
        returned arrays are fresh; :meth:`contact_terms` reads the same call's Delassus terms.
        """
        (out,) = self.function(
            state.q, state.v, tau, None, None, state.normal_rows, state.gap, state.normal_velocity
        )
        out = self._last = out.copy()
        a, b, c, _ = self._split
        return out[:a], out[a:b], out[b:c]

    def contact_terms(self, indices: NDArray[np.intp]) -> tuple[Vector, Vector]:
        r""":math:`W^{-1} J_a^T` (N, m) and :math:`J_a W^{-1} J_a^T` (m, m) of rows ``indices``.

        From the last :meth:`__call__` (the same step).
        """
        assert self._last is not None
        size, n = self._sizes
        _, _, c, d = self._split
        Winv_Jt = self._last[c:d].reshape((size, n), order="F")
        delassus = self._last[d:].reshape((n, n), order="F")
        return Winv_Jt[:, indices], delassus[indices[:, None], indices]


def _constant_terms(
    nv: int,
    size: int,
    dt: float,
    theta: float,
    flexible: FlexibleJoints | None,
    viscous: Vector | None,
) -> tuple[Vector, Vector, Vector]:
    """:math:`W_0`, :math:`K_q` and F of the module docstring, each (size, size)."""
    ht = dt * theta
    W0, Kq, F = np.zeros((size, size)), np.zeros((size, size)), np.zeros((size, size))
    if flexible is not None:
        Kq = flexible.coupling_matrix(flexible.stiffness)
        damping = flexible.coupling_matrix(flexible.damping)
        W0 = ht * damping + ht * ht * Kq
        W0[nv:, nv:] += np.diag(flexible.motor_inertia)
        F = damping + ht * Kq
    if viscous is not None:
        links = np.arange(nv)
        W0[links, links] += ht * viscous
        F[links, links] += viscous
    return W0, Kq, F


def _cholesky(W: Any) -> list[list[Any]]:
    """Lower Cholesky factor of the symmetric positive definite expression W (n, n), by rows."""
    import casadi as ca

    n = W.shape[0]
    L: list[list[Any]] = [[None] * n for _ in range(n)]
    for j in range(n):
        L[j][j] = ca.sqrt(W[j, j] - sum((L[j][k] ** 2 for k in range(j)), ca.SX(0)))
        for i in range(j + 1, n):
            dot = sum((L[i][k] * L[j][k] for k in range(j)), ca.SX(0))
            L[i][j] = (W[i, j] - dot) / L[j][j]
    return L


def _cholesky_solve(L: list[list[Any]], B: Any) -> Any:
    """:math:`W^{-1} B` with :math:`W = L L^T` (:func:`_cholesky`), B of shape (n, k)."""
    import casadi as ca

    n, k = B.shape
    columns = []
    for c in range(k):
        y: list[Any] = []
        for i in range(n):  # L y = b
            y.append((B[i, c] - sum((L[i][j] * y[j] for j in range(i)), ca.SX(0))) / L[i][i])
        x: list[Any] = [None] * n
        for i in reversed(range(n)):  # L^T x = y
            rest = sum((L[j][i] * x[j] for j in range(i + 1, n)), ca.SX(0))
            x[i] = (y[i] - rest) / L[i][i]
        columns.append(ca.vertcat(*x))
    return ca.horzcat(*columns)
