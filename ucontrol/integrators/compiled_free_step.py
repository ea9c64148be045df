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

With ``single_rows``, the call also solves, for each constraint i in parallel, the step in
which i alone is active, as the closed form of the one-row LCP
(:func:`~ucontrol.solvers.lcp_refinement.single_constraint_solution`) with the rules of
:class:`~ucontrol.integrators.moreau_jean.MoreauJean` (Newton's law on closing constraints,
the closure :math:`g_i / \mathrm{h}` of a held constraint still open, the energy guard):

.. math::

    d_i = J_i W^{-1} J_i^T, \quad \beta_i = J_i v^{free} + c_i + e_i u_i^-, \quad
    P_i = \max(0, -\beta_i / d_i), \quad
    v_{k+1} = v^{free} + W^{-1} J_i^T P_i,

so that a step with one active row (the common contact step) needs no further array work.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from ucontrol.model.flexible_joints import FlexibleJoints
from ucontrol.plant import PlantEvaluation

if TYPE_CHECKING:
    from ucontrol.contact.compiled_rows import ConstraintRows

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
        single_rows: SingleRowRules | None = None,
    ) -> None:
        import casadi as ca  # imported only for the steps that use it

        from ucontrol.model.compiled_function import CompiledFunction

        nv = data_nle.size
        size = nv if flexible is None else nv + flexible.nf
        W0, Kq, F = _constant_terms(nv, size, dt, theta, flexible, viscous)
        q, v, tau = ca.SX.sym("q", size), ca.SX.sym("v", size), ca.SX.sym("tau", size)
        M_upper, nle = ca.SX.sym("M", nv, nv), ca.SX.sym("nle", nv)
        # The rows as ConstraintRows writes them, row by row: the columns of Jᵀ (nv, n).
        rows_t, gap, velocity = ca.SX.sym("J_t", nv, n), ca.SX.sym("gap", n), ca.SX.sym("u", n)
        rows = rows_t.T
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
        delassus = J @ Winv_Jt
        parts = [
            v_free,
            q + h * ((1.0 - th) * v + th * v_free),
            gap + gh * velocity,
            ca.vec(Winv_Jt),
            ca.vec(delassus),
        ]
        activation, kinetic = ca.SX.sym("activation", n), ca.SX.sym("kinetic", 1)
        inputs = [q, v, tau, M_upper, nle, rows_t, gap, velocity, W0_s, Kq_s, F_s, scalars]
        if single_rows is not None:
            inputs += [activation, kinetic]
            for i in range(n):
                parts.append(
                    _single_row_step(
                        i, single_rows, q, v, J, v_free, Winv_Jt, delassus, gap, velocity,
                        activation, kinetic, h, th,
                    )
                )  # fmt: skip
        self.function = CompiledFunction(ca.Function("free_step", inputs, [ca.vertcat(*parts)]))
        self.compiled = self.function.compiled
        if self.compiled:
            self.function.bind_input(3, data_M)
            self.function.bind_input(4, data_nle)
        for i, value in ((8, W0), (9, Kq), (10, F)):
            self.function.input_view(i)[...] = value
        self.function.input_buffer(11)[:] = (dt, theta, horizon)
        self.single_rows = single_rows is not None
        self._source: ConstraintRows | None = None  # see read_rows_of
        self._sizes = (size, n)
        # Ends of the outputs v_free, q_free, predicted gaps, W⁻¹Jᵀ, JW⁻¹Jᵀ (Python ints).
        self._split = tuple(np.cumsum([size, size, n, size * n, n * n]).tolist())
        self._kinetic = self.function.input_buffer(13) if self.single_rows else None
        # The per-step inputs, written in place: q, v, tau, J (row by row), gaps, normal
        # velocities.
        self._inputs = tuple(
            self.function.input_buffer(i) if i == 5 else self.function.input_view(i)
            for i in (0, 1, 2, 5, 6, 7)
        )
        self._run, self._out = self.function.runner(), self.function.output_buffer(0)
        self._last: Vector | None = None  # the last call's outputs

    def __call__(self, state: PlantEvaluation, tau: Vector) -> tuple[Vector, Vector, Vector]:
        """:math:`v^{free}`, :math:`q^{free}` (each (N,)) and the predicted gaps (n,).

        ``state`` must carry its normal rows (:attr:`PlantEvaluation.normal_rows`). The
        returned arrays are fresh; :meth:`contact_terms` reads the same call's Delassus terms.
        """
        if self._kinetic is not None:
            self._kinetic[0] = state.kinetic_energy
        q, v, tau_in, J, gap, velocity = self._inputs
        source = self._source
        if source is not None and state.normal_rows is source.last_rows:
            tau_in[...] = tau  # q, v and the rows: in the inputs and outputs of that call
        else:  # (into the rows' buffers if bound: they no longer hold their last call)
            if source is not None:
                source.last_rows = None
            rows = state.normal_rows
            assert rows is not None
            q[...], v[...], tau_in[...] = state.q, state.v, tau
            J[...], gap[...], velocity[...] = rows.reshape(-1), state.gap, state.normal_velocity
        self._run()
        out = self._last = self._out.copy()
        a, b, c = self._split[:3]
        return out[:a], out[a:b], out[b:c]

    def read_rows_of(self, rows: ConstraintRows) -> None:
        """Read q, v and the rows from ``rows``' buffers when a state is its last call's.

        Binds those inputs to the memory ``rows`` wrote them to (its inputs q, v and its
        output), so that a step from the evaluation ``rows`` made last copies only tau (as M
        and h, which the step reads from the data, the state must be the last evaluation).
        For a rigid robot (q and v of the rows' size).
        """
        q, v, out = rows.buffers()
        n, nv = self._sizes[1], q.size
        if self._sizes[0] != nv:
            raise ValueError(f"rows of nv = {nv} for a step of size {self._sizes[0]}")
        function = self.function
        function.bind_input(0, q)
        function.bind_input(1, v)
        function.bind_input(5, out[2 * n :])
        function.bind_input(6, out[:n])
        function.bind_input(7, out[n : 2 * n])
        self._inputs = tuple(function.input_buffer(i) for i in (0, 1, 2, 5, 6, 7))
        self._source = rows

    def contact_terms(self, indices: NDArray[np.intp]) -> tuple[Vector, Vector]:
        r""":math:`W^{-1} J_a^T` (N, m) and :math:`J_a W^{-1} J_a^T` (m, m) of rows ``indices``.

        From the last :meth:`__call__` (the same step).
        """
        assert self._last is not None
        size, n = self._sizes
        c, d, e = self._split[2:]
        Winv_Jt = self._last[c:d].reshape((size, n), order="F")
        delassus = self._last[d:e].reshape((n, n), order="F")
        if indices.size == n:  # every row: the indexing's values in its memory orders
            return Winv_Jt, np.ascontiguousarray(delassus)
        return Winv_Jt[:, indices], delassus[indices[:, None], indices]

    def bind_activation(self, activation: Vector) -> None:
        """Read the persistence memory (n,) of the integrator from ``activation`` at every call.

        Its values at the call are those of the step's active set (the single-row steps read
        which constraints are held).
        """
        self.function.bind_input(12, activation)

    def single_row(self, i: int) -> SingleRowStep:
        """The last call's step with constraint ``i`` alone active (views of its outputs)."""
        assert self._last is not None and self.single_rows
        size = self._sizes[0]
        start = self._split[-1] + i * (5 + 2 * size)
        block = self._last[start : start + 5 + 2 * size]
        _, _, residual, solved, plastic = block[:5].tolist()
        values = (
            block[0:1],
            block[1:2],
            residual,
            solved > 0.0,
            plastic > 0.0,
            block[5 : 5 + size],
            block[5 + size :],
        )
        return tuple.__new__(SingleRowStep, values)  # type: ignore[type-var]  # (no __new__)


class SingleRowStep(NamedTuple):
    """The step with one constraint alone active, from :meth:`CompiledFreeStep.single_row`.

    Attributes:
        impulse: Its impulse P in [N s], shape (1,).
        velocity: The LCP's velocity ``d P + β`` in [m/s], shape (1,).
        residual: The natural-map residual in [m/s].
        solved: Whether the closed form solves it (d > 0 or β >= 0).
        plastic: Whether the energy guard made it plastic.
        v: :math:`v_{k+1}`, shape (N,).
        q: :math:`q_{k+1}`, shape (N,).
    """

    impulse: Vector
    velocity: Vector
    residual: float
    solved: bool
    plastic: bool
    v: Vector
    q: Vector


class SingleRowRules(NamedTuple):
    """What :class:`~ucontrol.integrators.moreau_jean.MoreauJean` applies to one active row.

    Attributes:
        restitution: Newton's restitution of each constraint, shape (n,).
        threshold: Closing speed below which no restitution applies, in [m/s] (or [rad/s]).
        energy_tolerance: Relative energy gain, of 1 + T, above which the step is made plastic.
    """

    restitution: Vector
    threshold: float
    energy_tolerance: float


def _single_row_step(
    i: int,
    rules: SingleRowRules,
    q: Any,
    v: Any,
    J: Any,
    v_free: Any,
    Winv_Jt: Any,
    delassus: Any,
    gap: Any,
    velocity: Any,
    activation: Any,
    kinetic: Any,
    h: Any,
    theta: Any,
) -> Any:
    """(P, w, residual, solved, plastic, v_{k+1}, q_{k+1}) of row i alone active (5 + 2N,)."""
    import casadi as ca

    d, u_free, u_minus = delassus[i, i], J[i, :] @ v_free, velocity[i]
    held_open = ca.logic_and(activation[i] > 0.0, gap[i] > 0.0)
    closure = ca.if_else(held_open, gap[i] / h, 0.0)
    e = float(rules.restitution[i])
    rebound = (
        ca.if_else(ca.logic_or(held_open, u_minus >= -rules.threshold), 0.0, e * u_minus)
        if e != 0.0
        else ca.SX(0.0)
    )
    b = u_free + closure

    def closed_form(beta: Any) -> tuple[Any, Any, Any]:
        impulse = ca.if_else(ca.logic_and(beta < 0.0, d > 0.0), -beta / d, 0.0)
        w = d * impulse + beta
        residual = ca.fabs(ca.fmin(ca.if_else(d > 0.0, d * impulse, impulse), w))
        return impulse, w, residual

    impulse, w, residual = closed_form(b + rebound)
    plastic = ca.SX(0.0)
    if e != 0.0:  # the energy guard, only where a rebound can be nonzero
        u_plus = w - rebound - (b - u_free)
        u_k = J[i, :] @ v
        gain = impulse * (0.5 * (u_free + u_plus) - theta * (u_free - u_k))
        plastic = ca.logic_and(rebound != 0.0, gain > rules.energy_tolerance * (1.0 + kinetic))
        impulse_0, w_0, residual_0 = closed_form(b)
        impulse = ca.if_else(plastic, impulse_0, impulse)
        w = ca.if_else(plastic, w_0, w)
        residual = ca.if_else(plastic, residual_0, residual)
    solved = ca.logic_or(d > 0.0, b + rebound >= 0.0)
    if e != 0.0:
        solved = ca.if_else(plastic, ca.logic_or(d > 0.0, b >= 0.0), solved)
    v_next = v_free + Winv_Jt[:, i] * impulse
    q_next = q + h * ((1.0 - theta) * v + theta * v_next)
    return ca.vertcat(impulse, w, residual, solved, plastic, v_next, q_next)


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
