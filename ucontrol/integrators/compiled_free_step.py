r"""The free part of a Moreau–Jean step in one compiled call.

Before its contact problem, a Moreau–Jean step of a robot whose joints are all vector spaces
(nq = nv: revolute and prismatic joints) computes, in numpy and LAPACK, a dozen small array
operations, each a Python call (:mod:`ucontrol.integrators.moreau_jean`). With every
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
on the motors, followed by the frictional contacts' tangential rows when the rows hold them
(``tangential``): :math:`W^{-1} [J^T\ T^T]` and the Delassus matrix of all the rows, of which a
contact step with friction reads its active rows' (:meth:`CompiledFreeStep.contact_terms`).
W is factored by casadi's symbolic Cholesky decomposition (``casadi.chol``) and two
triangular solves; the results equal the reference stages to round-off. The same call
applies the impact law (:func:`~ucontrol.integrators.step_stages.newton_offsets`, on casadi's
symbols) to every row as if it were active, with the rows held by the step memory's
activation: the contact problem of the step reads the active rows' terms (:meth:`offsets`).
The restitutions are an input of the call, written once at construction, not constants of its
C: one library serves every restitution (a Monte Carlo over restitution compiles it once). Only
the rows without restitution (joint stops, plastic contacts) read a constant 0, so that their
rebound and the energy guard of their one-row steps are not evaluated at every call.

With ``single_rows``, the call also solves, for each constraint i in parallel, the step in
which i alone is active, as the closed form of the one-row LCP
(:func:`~ucontrol.solvers.lcp_refinement.single_constraint_solution`) with the rules of
:class:`~ucontrol.integrators.moreau_jean.MoreauJean` (Newton's law on closing constraints,
the closure :math:`g_i / \mathrm{h}` of a held constraint still open, the energy guard):

.. math::

    d_i = J_i W^{-1} J_i^T, \quad \beta_i = J_i v^{free} + c_i + e_i u_i^-, \quad
    P_i = \max(0, -\beta_i / d_i), \quad
    v_{k+1} = v^{free} + W^{-1} J_i^T P_i,

so that a step with one active row (the common contact step) needs no further array work:
the call also applies the active-set rule past a run's first step
(:func:`~ucontrol.integrators.step_stages.is_active`, on casadi's symbols) and gives the number
of its row when it has one (:meth:`CompiledFreeStep.run`), and whether
each one-row step is an impact (:func:`~ucontrol.integrators.step_stages.is_impact`).

On a rigid robot with a free-flyer root (``positions=False``: q of size nq = nv + 1, on
:math:`\mathbb{R}^3 \times SO(3)`) the call has no q and gives no :math:`q^{free}` nor one-row
steps: the velocity-space terms above (:math:`v^{free}`, the predicted gaps, the Delassus terms
and the impact law) are the same, and the integrator advances the configuration on its
manifold (a table on four feet, a quadruped).
"""

from __future__ import annotations

import itertools
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from ucontrol.exceptions import InvalidParameterError
from ucontrol.integrators import step_stages
from ucontrol.integrators.step_stages import (
    NO_ACTIVE_ROW,
    SEVERAL_ACTIVE_ROWS,
    ArrayOps,
    gains_energy,
    impulse_energy_gain,
    is_active,
    is_impact,
    newton_offsets,
    predicted_gaps,
    theta_displacement,
)
from ucontrol.model.flexible_joints import FlexibleJoints
from ucontrol.plant import PlantEvaluation
from ucontrol.solvers.compiled_active_set import (
    CONVERGENCE,
    MAX_ROWS,
    SWEEPS,
    active_set_terms,
)
from ucontrol.solvers.lcp_refinement import POLISH_THRESHOLD, RANK_TOLERANCE

if TYPE_CHECKING:
    from ucontrol.contact.compiled_rows import ConstraintRows

Vector = NDArray[np.float64]

#: The modules whose code writes the compiled call (part of its definition key).
_GENERATED_BY = (
    "ucontrol.integrators.compiled_free_step",
    "ucontrol.integrators.step_stages",
    "ucontrol.model.compiled_function",
    "ucontrol.solvers.compiled_active_set",
)
#: The constants of :mod:`~ucontrol.integrators.step_stages` (part of the definition key).
_STAGE_CONSTANTS = (
    "ENERGY_GAIN_TOLERANCE",
    "START_GAP_TOLERANCE",
    "IMPACT_VELOCITY_THRESHOLD",
    "HELD_IMPACT_VELOCITY",
)
#: The inputs written (or bound) at every step besides tau and the kinetic energy, in this
#: order.
_STEP_INPUTS = ("q", "v", "J_t", "gap", "u")


class CompiledFreeStep:
    """The free velocity, free configuration, predicted gaps, impact law and Delassus terms.

    Args:
        data_M: The Pinocchio data's mass matrix buffer (upper triangle read), shape (nv, nv).
        data_nle: The Pinocchio data's nonlinear-effects buffer, shape (nv,).
        n: Number of constraints.
        dt: Step h in [s].
        theta: θ of the position update.
        horizon: γ h, the active-set prediction horizon in [s].
        flexible: The flexible joints, or None.
        viscous: Viscous joint friction D on the links, shape (nv,), or None.
        rules: The impact law's parameters (:class:`ImpactRules`).
        single_rows: Whether the call also solves the steps with one active row (the
            solver's one-row solve is the closed form); only with ``positions``.
        positions: Whether q is a vector of the step's size (nq = nv: every joint a vector
            space), so that the call also gives :math:`q^{free}`. Without (a free-flyer
            root, rigid) the call has no q and gives the velocity-space terms alone: the
            caller advances the configuration on its manifold.
        tangential: Number k of tangential rows after the n normal ones (those of
            :class:`~ucontrol.contact.compiled_rows.ConstraintRows`), whose Delassus terms
            the call also gives (the impact law and the one-row steps read the normal rows).

    Raises:
        InvalidParameterError: ``positions`` is False with ``single_rows`` or ``flexible``.

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
        rules: ImpactRules,
        single_rows: bool = False,
        positions: bool = True,
        tangential: int = 0,
        several_rows: bool = False,
    ) -> None:
        from ucontrol.model.compile_cache import definition_key
        from ucontrol.model.compiled_function import CompiledFunction

        nv = data_nle.size
        size = nv if flexible is None else nv + flexible.nf
        if not positions and (single_rows or several_rows or flexible is not None):
            raise InvalidParameterError(
                "positions", positions, "True with one-row or several-row steps or flexible joints"
            )
        if several_rows and n < 2:
            raise InvalidParameterError("several_rows", several_rows, f"False with {n} constraint")
        W0, Kq, F = _constant_terms(nv, size, dt, theta, flexible, viscous)
        restitution = np.asarray(rules.restitution, dtype=float)
        elastic = tuple(bool(e) for e in restitution.tolist())  # the rows with a rebound
        # What the Function is built from: casadi is imported only to build it (a cache miss).
        # (with the shared stages' tolerances as they are now: constants of the Function)
        definition = definition_key(
            ["free_step", nv, size, n, float(rules.threshold), rules.newton_law, elastic,
             single_rows, positions, tangential,
             *(getattr(step_stages, name) for name in _STAGE_CONSTANTS)],
            _GENERATED_BY,
        )  # fmt: skip
        self.function = CompiledFunction.cached(
            "free_step",
            definition,
            lambda: _free_step_function(
                nv, size, n, rules, elastic, single_rows, positions, tangential
            ),
        )
        self.compiled = self.function.compiled
        index = self.function.index_in  # inputs bound by name
        if self.compiled:
            self.function.bind_input(index("M"), data_M)
            self.function.bind_input(index("nle"), data_nle)
        for name, value in (("W0", W0), ("Kq", Kq), ("F", F), ("restitution", restitution)):
            self.function.input_view(index(name))[...] = value
        self.function.input_buffer(index("scalars"))[:] = (dt, theta, horizon)
        self.single_rows = single_rows
        self._sizes = (size, n)
        self._rows = n + tangential  # normal and tangential rows of the Delassus terms
        # Ends of the outputs v_free, q_free (none without positions), predicted gaps, W⁻¹Jᵀ,
        # JW⁻¹Jᵀ (of every row), rebound and closure terms, the active set's count and index
        # (Python ints).
        q_size, r = (size if positions else 0), self._rows
        self._split = tuple(np.cumsum([size, q_size, n, size * r, r * r, r, r, 1]).tolist())
        self._ends = self._split[:3]  # those of the free terms (free_terms)
        self._active_row_at = self._split[7] - 1  # where the active set's row is
        # Each one-row step's outputs: the impulses of every row (n,), its impulse and LCP
        # velocity (1,) each, its scalars (_SINGLE_ROW_SCALARS,), v_{k+1}, q_{k+1} (N,) each.
        self._row_slices = _one_row_slices(self._split[-1], n, size) if single_rows else ()
        # The several-row step (a Function of its own, run only for those steps): its outputs
        # the impulses and LCP velocities of every row (n,) each, its scalars
        # (_SEVERAL_ROW_SCALARS,), v_{k+1} and q_{k+1} (N,) each.
        ends = np.cumsum([0, n, n, _SEVERAL_ROW_SCALARS, size, size]).tolist()
        self._several_slices = tuple(slice(a, b) for a, b in itertools.pairwise(ends))
        # Loaded by the first step with several active rows (_load_several_rows): a run without
        # one neither builds nor loads it.
        self._several: CompiledFunction | None = None
        # (the ends of the terms it reads: v_free, q_free, gaps, W⁻¹Jᵀ, JW⁻¹Jᵀ, impact law)
        self._several_definition = (nv, size, n, tuple(self._split), rules, elastic)
        self._elastic = elastic  # the rows whose rebound terms are not constants 0
        self.several_rows = several_rows
        self._positions = positions
        buffer = self.function.input_buffer
        self._activation = buffer(index("activation"))
        # The per-step inputs, written in place: q (none without positions), then v, J (row by
        # row), gaps, normal velocities.
        self._q_input = self.function.input_view(index("q")) if positions else None
        self._inputs = tuple(
            buffer(index(name)) if name == "J_t" else self.function.input_view(index(name))
            for name in _STEP_INPUTS[1:]
        )
        # A call writes tau and the kinetic energy, its arguments, first.
        self._run = self.function.runner((index("tau"), index("kinetic")))
        self._out = self.function.output_buffer(0)
        self._last: Vector | None = None  # the last call's outputs
        self._activation_source: Vector | None = None  # the activation input's last source
        self._source: ConstraintRows | None = None  # see read_rows_of
        self._bind_several_rows()

    def use_restitution(self, restitution: Vector) -> None:
        """Apply Newton's law with ``restitution`` (n,) from now on: an input of the call.

        Raises:
            InvalidParameterError: ``restitution`` is 0 where the call's is not, or the
                converse (the rebound terms of the rows without restitution are constants 0
                of the call).
        """
        elastic = self._elastic
        given = np.asarray(restitution, dtype=float)
        if given.shape != (len(elastic),) or tuple((given != 0.0).tolist()) != elastic:
            raise InvalidParameterError(
                "restitution", given.tolist(), f"non-zero exactly where {list(elastic)}"
            )
        self.function.input_view(self.function.index_in("restitution"))[...] = given

    def __call__(
        self, state: PlantEvaluation, tau: Vector, activation: Vector
    ) -> tuple[Vector, Vector | None, Vector]:
        """:meth:`run`, then its :meth:`free_terms`."""
        self.run(state, tau, activation)
        return self.free_terms()

    def run(self, state: PlantEvaluation, tau: Vector, activation: Vector) -> float:
        """Run the call of a step from ``state`` under forces ``tau`` (N,).

        ``state`` must carry its normal rows (:attr:`PlantEvaluation.normal_rows`);
        ``activation`` (n,) is the step memory's (the impact law reads which constraints are
        held); a read-only one (the memories shared between steps) is copied into the call's
        input only when it is not the array copied last. :meth:`free_terms`,
        :meth:`contact_terms`, :meth:`offsets` and :meth:`single_row` read the call's outputs.

        Returns:
            The row of the active set by :func:`~ucontrol.integrators.step_stages.is_active`
            with ``activation`` (the rule past a run's first step, without contacts barred
            from closing) when it has one row, else
            :data:`~ucontrol.integrators.step_stages.NO_ACTIVE_ROW` or
            :data:`~ucontrol.integrators.step_stages.SEVERAL_ACTIVE_ROWS`, as a float.
        """
        if activation is not self._activation_source:  # (a writeable one is never kept)
            self._activation[:] = activation
            # A read-only array is unchanged until replaced: the next call need not copy it.
            self._activation_source = None if activation.flags.writeable else activation
        source = self._source
        # q, v and the rows of the rows' last call: in the inputs and outputs of that call
        if source is None or state.normal_rows is not source.last_rows:
            q, (v, J, gap, velocity) = self._q_input, self._inputs
            # (into the rows' buffers if bound: they no longer hold their last call)
            if source is not None:
                source.last_rows = None
            rows = state.normal_rows
            assert rows is not None
            if q is not None:
                q[...] = state.q
            # (the tangential rows, after the normal ones, are the rows' last call's: the
            # frictional step reads them only from that call, MoreauJean._contact_outcome)
            v[...], J[: rows.size] = state.v, rows.reshape(-1)
            gap[...], velocity[...] = state.gap, state.normal_velocity
        self._run(tau, state.kinetic_energy)
        out = self._last = self._out.copy()
        return out.item(self._active_row_at)

    def free_terms(self) -> tuple[Vector, Vector | None, Vector]:
        """:math:`v^{free}`, :math:`q^{free}` (each (N,); None without ``positions``), gaps (n,).

        Of the last :meth:`run` (views of its fresh outputs); the gaps are the predicted ones.
        """
        assert self._last is not None
        out, (a, b, c) = self._last, self._ends
        return out[:a], out[a:b] if self._positions else None, out[b:c]

    def read_rows_of(self, rows: ConstraintRows) -> None:
        """Read q, v and the rows in place from ``rows``' buffers when a state is its last call's.

        Binds those inputs to the memory ``rows`` wrote them to (its inputs q, v and its
        output), so that a step from the evaluation ``rows`` made last copies only tau (as M
        and h, which the step reads from the data, the state must be the last evaluation): the
        copies cost more than 5 % of a two-link step (docs/benchmarks.md). For a rigid robot
        (v of the rows' size; q too with ``positions``).
        """
        q, v, out = rows.buffers()
        n, nv = self._sizes[1], v.size
        if self._sizes[0] != nv or n + rows.tangential != self._rows:
            raise ValueError(
                f"rows of nv = {nv}, {n + rows.tangential} rows for a step of size "
                f"{self._sizes[0]}, {self._rows} rows"
            )
        function, index = self.function, self.function.index_in
        for name, buffer in (
            ("q", q), ("v", v), ("J_t", out[2 * n :]), ("gap", out[:n]), ("u", out[n : 2 * n])
        ):  # fmt: skip
            if name != "q" or self._positions:
                function.bind_input(index(name), buffer)
        self._q_input = function.input_buffer(index("q")) if self._positions else None
        self._inputs = tuple(function.input_buffer(index(name)) for name in _STEP_INPUTS[1:])
        self._source = rows
        self._bind_several_rows()

    def _bind_several_rows(self) -> None:
        """Bind the several-row step's inputs to this call's outputs and inputs' memory.

        Its inputs are the terms this call wrote last and the step's inputs as this call
        reads them (bound where this call's are): a run copies nothing.
        """
        several = self._several
        if several is None:  # (not loaded yet: bound when it is)
            return
        free = self.function
        terms = self._out[: self._split[-1]]  # (those before the one-row steps')
        several.bind_input(several.index_in("terms"), terms)
        for name in ("q", "v", "J_t", "u", "activation", "scalars", "kinetic"):
            several.bind_input(several.index_in(name), free.input_buffer(free.index_in(name)))
        self._several_run = several.runner()
        self._several_out = several.output_buffer(0)

    def _load_several_rows(self) -> bool:
        """Build or load the several-row step's library and bind it; whether it is compiled.

        Where it does not compile, :attr:`several_rows` becomes False: the caller's contact
        step solves those steps.
        """
        from ucontrol.model.compile_cache import definition_key
        from ucontrol.model.compiled_function import CompiledFunction

        nv, size, n, split, rules, elastic = self._several_definition
        key = definition_key(
            ["several_row_step", nv, size, n, split, rules.newton_law, elastic, SWEEPS,
             CONVERGENCE, RANK_TOLERANCE,
             *(getattr(step_stages, name) for name in _STAGE_CONSTANTS)],
            _GENERATED_BY,
        )  # fmt: skip
        several = CompiledFunction.cached(
            "several_row_step",
            key,
            lambda: _several_row_function(nv, size, n, split, rules, elastic),
        )
        if not several.compiled:
            self.several_rows = False
            return False
        self._several = several
        self._bind_several_rows()
        return True

    def contact_terms(self, indices: NDArray[np.intp]) -> tuple[Vector, Vector]:
        r""":math:`W^{-1} J_a^T` (N, m) and :math:`J_a W^{-1} J_a^T` (m, m) of rows ``indices``.

        From the last :meth:`__call__` (the same step); ``indices`` among the n normal rows,
        then the ``tangential`` ones.
        """
        assert self._last is not None
        size, n = self._sizes[0], self._rows
        c, d, e = self._split[2:5]
        Winv_Jt = self._last[c:d].reshape((size, n), order="F")
        delassus = self._last[d:e].reshape((n, n), order="F")
        if indices.size == n:  # every row: the indexing's values in its memory orders
            return Winv_Jt, np.ascontiguousarray(delassus)
        return Winv_Jt[:, indices], delassus[indices[:, None], indices]

    def offsets(self, indices: NDArray[np.intp]) -> tuple[Vector, Vector]:
        r"""The impact law of rows ``indices``: rebound and closure terms (m,) each, in [m/s].

        :func:`~ucontrol.integrators.step_stages.newton_offsets` of the last
        :meth:`__call__`, with the rows held by its ``activation``; 0 on the ``tangential``
        rows (``indices`` as in :meth:`contact_terms`).
        """
        assert self._last is not None
        e, f, g = self._split[4:7]
        return self._last[e:f][indices], self._last[f:g][indices]

    def single_row(self, i: int) -> SingleRowStep:
        """The last call's step with constraint ``i`` alone active (views of its outputs).

        A plain tuple of :class:`SingleRowStep`'s fields, in its order (one step's NamedTuple
        fewer).
        """
        assert self._last is not None and self.single_rows
        last = self._last
        impulses, P, w, scalars, v_next, q_next = self._row_slices[i]
        impulse, _, residual, solved, plastic, impact = last[scalars].tolist()
        return (
            last[impulses],
            last[P],
            last[w],
            impulse,
            residual,
            solved > 0.0,
            plastic > 0.0,
            impact > 0.0,
            last[v_next],
            last[q_next],
        )

    def several_row(self) -> SeveralRowStep | None:
        """The last run's step with its active set of several rows, or None if not solved.

        The exact solve on the rows of the active set held by the step memory (the
        active-set start of :class:`~ucontrol.solvers.ProxsuiteLCPSolver`, by a second
        compiled call on the last run's terms:
        :func:`~ucontrol.solvers.compiled_active_set.active_set_terms`), None
        where it does not solve the step's LCP or the energy guard refuses its impulses (the
        caller's contact step then solves it). Views of the outputs, the masks as Python
        ints. The first call builds or loads the compiled library.
        """
        assert self._last is not None and self.several_rows
        if self._several is None and not self._load_several_rows():
            return None
        self._several_run()  # (on the last run's terms, still in the output buffer)
        last = self._several_out.copy()
        impulses, velocity, scalars, v_next, q_next = self._several_slices
        residual, active, held, impacts = last[scalars].tolist()
        if not residual <= POLISH_THRESHOLD:  # (also NaN)
            return None
        return (
            last[impulses], last[velocity], residual, int(active), int(held), int(impacts),
            last[v_next], last[q_next],
        )  # fmt: skip


#: The scalars of a one-row step's block of outputs, after the impulses of every row: P, w, the
#: residual, whether solved, plastic and an impact.
_SINGLE_ROW_SCALARS = 6


def _one_row_slices(first: int, n: int, size: int) -> tuple[tuple[slice, ...], ...]:
    """Where the outputs of each one-row step are, those of the first at ``first``.

    For each of the n rows: its impulses of every row (n,), its P (1,), w (1,), its scalars
    (:data:`_SINGLE_ROW_SCALARS`,), :math:`v_{k+1}` and :math:`q_{k+1}` (``size``,) each.
    """
    block = n + _SINGLE_ROW_SCALARS + 2 * size
    slices = []
    for start in range(first, first + n * block, block):
        scalars = start + n
        velocity = scalars + _SINGLE_ROW_SCALARS  # v_{k+1}, then q_{k+1}
        slices.append((
            slice(start, scalars),
            slice(scalars, scalars + 1),
            slice(scalars + 1, scalars + 2),
            slice(scalars, velocity),
            slice(velocity, velocity + size),
            slice(velocity + size, velocity + 2 * size),
        ))  # fmt: skip
    return tuple(slices)


#: The step with one constraint alone active, from :meth:`CompiledFreeStep.single_row`: the
#: normal impulses of every constraint in [N s] (n,), its own P (1,), the LCP's velocity
#: d P + β in [m/s] (1,), P as a float, the natural-map residual in [m/s], whether the closed
#: form solves it (d > 0 or β >= 0), whether the energy guard made it plastic, whether it is an
#: impact (:func:`~ucontrol.integrators.step_stages.is_impact`), :math:`v_{k+1}` (N,) and
#: :math:`q_{k+1}` (N,).
SingleRowStep = tuple[Vector, Vector, Vector, float, float, bool, bool, bool, Vector, Vector]

#: The scalars of the several-row step's block of outputs: the residual and the masks of the
#: active, held and impact rows.
_SEVERAL_ROW_SCALARS = 4

#: The step with several active rows, from :meth:`CompiledFreeStep.several_row`: the normal
#: impulses (n,) in [N s] and LCP velocities D P + b (n,) in [m/s] of every row (those of the
#: rows outside the active set meaningless), the natural-map residual in [m/s], the masks
#: (bit i for constraint i) of the active rows, of the rows with an impulse (held at the next
#: step) and of the impacts (:func:`~ucontrol.integrators.step_stages.is_impact`),
#: :math:`v_{k+1}` (N,) and :math:`q_{k+1}` (N,).
SeveralRowStep = tuple[Vector, Vector, float, int, int, int, Vector, Vector]


class ImpactRules(NamedTuple):
    """The impact law of :class:`~ucontrol.integrators.moreau_jean.MoreauJean`'s normal rows.

    Attributes:
        restitution: Newton's restitution of each constraint, shape (n,).
        threshold: Closing speed below which no restitution applies, in [m/s] (or [rad/s]).
        newton_law: ``"closing"`` (with the energy guard) or ``"siconos"`` (without).
    """

    restitution: Vector
    threshold: float
    newton_law: str


def _free_step_function(
    nv: int,
    size: int,
    n: int,
    rules: ImpactRules,
    elastic: tuple[bool, ...],
    single_rows: bool,
    positions: bool,
    tangential: int,
) -> Any:
    """The casadi Function of :class:`CompiledFreeStep` (the module docstring's terms).

    ``elastic``: whether each row's restitution is non-zero (n,); the others read a constant 0
    (their rebound terms fold away). Without ``positions`` the Function has no input q (a
    rigid robot's stiffness terms are 0) and no output :math:`q^{free}`. ``tangential`` rows
    follow the n normal ones in the input ``J_t`` and the Delassus terms.
    """
    import casadi as ca  # imported only for the steps that use it, and only to build

    q = ca.SX.sym("q", size) if positions else ca.SX.zeros(size)
    v, tau = ca.SX.sym("v", size), ca.SX.sym("tau", size)
    M_upper, nle = ca.SX.sym("M", nv, nv), ca.SX.sym("nle", nv)
    # The rows as ConstraintRows writes them, row by row: the columns of Jᵀ (nv, n + k).
    rows_t = ca.SX.sym("J_t", nv, n + tangential)
    gap, velocity = ca.SX.sym("gap", n), ca.SX.sym("u", n)
    rows = rows_t.T
    W0_s, Kq_s, F_s = (ca.SX.sym(name, size, size) for name in ("W0", "Kq", "F"))
    scalars = ca.SX.sym("scalars", 3)  # h, θ, γh
    h, th, gh = scalars[0], scalars[1], scalars[2]
    M = ca.triu(M_upper) + ca.triu(M_upper, False).T
    W = W0_s + ca.diagcat(M, ca.SX.zeros(size - nv, size - nv))
    force = tau - ca.vertcat(nle, ca.SX.zeros(size - nv)) - Kq_s @ q - F_s @ v
    J = ca.horzcat(rows, ca.SX.zeros(n + tangential, size - nv))
    R = ca.chol(W)  # W = RᵀR, R upper triangular: two triangular solves
    v_free = v + ca.solve(R, ca.solve(R.T, h * force))
    Winv_Jt = ca.solve(R, ca.solve(R.T, J.T))
    delassus = J @ Winv_Jt
    activation, kinetic = ca.SX.sym("activation", n), ca.SX.sym("kinetic", 1)
    # An input, not constants: one library serves every restitution (Monte Carlo draws).
    restitution_s = ca.SX.sym("restitution", n)
    law_restitution = ca.vertcat(
        *(restitution_s[i] if rebound else ca.SX(0.0) for i, rebound in enumerate(elastic))
    )
    offsets = newton_offsets(
        _casadi_ops(),
        gap,
        velocity,
        law_restitution,
        activation > 0.0,
        h,
        rules.threshold,
        rules.newton_law == "siconos",
        not any(elastic),
    )  # the impact law of every row, each as if active
    predicted = predicted_gaps(gap, velocity, gh)
    parts = [
        v_free,
        *([q + theta_displacement(v, v_free, h, th)] if positions else []),
        predicted,
        ca.vec(Winv_Jt),
        ca.vec(delassus),
        *(ca.vertcat(offset, ca.SX.zeros(tangential)) for offset in offsets),
    ]
    # The active set past a run's first step: its row when it has one, else NO_ACTIVE_ROW or
    # SEVERAL_ACTIVE_ROWS.
    active = is_active(predicted, activation)  # 1 or 0 per row
    count, row = ca.sum1(active), ca.dot(active, ca.DM(np.arange(n, dtype=float)))
    several = ca.if_else(count == 0.0, NO_ACTIVE_ROW, SEVERAL_ACTIVE_ROWS)
    parts.append(ca.if_else(count == 1.0, row, several))
    inputs = [q, v, tau, M_upper, nle, rows_t, gap, velocity, W0_s, Kq_s, F_s, scalars]
    inputs += [activation, kinetic, restitution_s]
    names = ["q", "v", "tau", "M", "nle", "J_t", "gap", "u", "W0", "Kq", "F", "scalars"]
    names += ["activation", "kinetic", "restitution"]
    if not positions:
        inputs, names = inputs[1:], names[1:]
    if single_rows:
        for i in range(n):
            parts.append(
                _single_row_step(
                    i, n, rules, q, v, J, v_free, Winv_Jt, delassus, offsets[0][i],
                    offsets[1][i], kinetic, h, th, activation[i], velocity[i],
                )
            )  # fmt: skip
    return ca.Function("free_step", inputs, [ca.vertcat(*parts)], names, ["terms"])


def _single_row_step(
    i: int,
    n: int,
    rules: ImpactRules,
    q: Any,
    v: Any,
    J: Any,
    v_free: Any,
    Winv_Jt: Any,
    delassus: Any,
    rebound: Any,
    closure: Any,
    kinetic: Any,
    h: Any,
    theta: Any,
    activation: Any,
    u_minus: Any,
) -> Any:
    """The step of row i alone active, of n constraints (n + 6 + 2N,).

    The impulses of every row (P at i, 0 elsewhere), then P, w, the residual, whether solved,
    plastic and an impact, :math:`v_{k+1}`, :math:`q_{k+1}`. ``rebound`` and ``closure`` are
    row i's impact law, ``activation`` and ``u_minus`` its memory's entry and normal velocity
    at step k; the energy guard and the impact rule are
    :mod:`~ucontrol.integrators.step_stages`'s, on casadi's symbols.
    """
    import casadi as ca

    ops = _casadi_ops()
    d, u_free = delassus[i, i], J[i, :] @ v_free
    b = u_free + closure

    def closed_form(beta: Any) -> tuple[Any, Any, Any, Any]:
        impulse = ca.if_else(ca.logic_and(beta < 0.0, d > 0.0), -beta / d, 0.0)
        w = d * impulse + beta
        residual = ca.fabs(ca.fmin(ca.if_else(d > 0.0, d * impulse, impulse), w))
        return impulse, w, residual, ca.logic_or(d > 0.0, beta >= 0.0)

    newton = closed_form(b + rebound)
    if rules.newton_law == "closing":  # the energy guard
        gain = impulse_energy_gain(ops, newton[0], u_free, newton[1] - rebound - closure,
                                   J[i, :] @ v, theta)  # fmt: skip
        plastic = ops.logical_and(rebound != 0.0, gains_energy(gain, kinetic))
        plastic_law = closed_form(b)
        impulse, w, residual, solved = (
            ca.if_else(plastic, x, y) for x, y in zip(plastic_law, newton, strict=True)
        )
    else:
        (impulse, w, residual, solved), plastic = newton, ca.SX(0.0)
    v_next = v_free + Winv_Jt[:, i] * impulse
    q_next = q + theta_displacement(v, v_next, h, theta)
    impact = is_impact(impulse, activation, u_minus)
    impulses = (impulse if j == i else ca.SX(0.0) for j in range(n))
    return ca.vertcat(*impulses, impulse, w, residual, solved, plastic, impact, v_next, q_next)


def _several_row_function(
    nv: int,
    size: int,
    n: int,
    split: tuple[int, ...],
    rules: ImpactRules,
    elastic: tuple[bool, ...],
) -> Any:
    r"""The casadi Function of the step of several active rows, solved on those the memory holds.

    Its inputs: the free step's ``terms`` up to its active row (``split``: the ends of
    :math:`v^{free}`, :math:`q^{free}`, the gaps, :math:`W^{-1}J^T`, :math:`JW^{-1}J^T`, the
    impact law's two terms and the active row; the one-row steps' after them unread), and the
    free step's ``q``, ``v``, ``J_t``, ``u``,
    ``activation``, ``scalars`` and ``kinetic``. The LCP of the active rows A (by
    :func:`~ucontrol.integrators.step_stages.is_active`), :math:`D_{AA} P_A + b_A` with
    :math:`b = J v^{free} + c + e u^-` (the impact law of every row, from the terms), is
    solved exactly on the rows of A whose ``activation`` is positive and checked on A
    (:func:`~ucontrol.solvers.compiled_active_set.active_set_terms`), the rows of A gathered
    into at most :data:`~ucontrol.solvers.compiled_active_set.MAX_ROWS` slots. Not accepted
    (an infinite residual) with more active rows than slots, or where the energy guard of the
    ``"closing"`` law refuses the impulses of rows with a rebound (the caller's step then
    solves the plastic problem).
    Outputs (2n + 4 + 2N,): the impulses and velocities of every row, the residual, the masks
    of the active rows, of those with an impulse and of the impacts (bit i for row i),
    :math:`v_{k+1}`, :math:`q_{k+1}`.
    """
    import casadi as ca

    terms = ca.SX.sym("terms", split[-1])
    q, v = ca.SX.sym("q", size), ca.SX.sym("v", size)
    rows_t, u_minus = ca.SX.sym("J_t", nv, n), ca.SX.sym("u", n)
    activation, scalars = ca.SX.sym("activation", n), ca.SX.sym("scalars", 3)
    kinetic = ca.SX.sym("kinetic", 1)
    J = ca.horzcat(rows_t.T, ca.SX.zeros(n, size - nv))
    v_free, _, predicted, Winv_Jt, delassus, rebound, closure = (
        terms[a:b] for a, b in itertools.pairwise((0, *split[:7]))
    )
    Winv_Jt, delassus = ca.reshape(Winv_Jt, size, n), ca.reshape(delassus, n, n)
    active = is_active(predicted, activation)
    b = J @ v_free + closure + rebound
    guess = active * (activation > 0.0)
    # The active rows gathered into K slots, in their order (row i into slot k when k rows
    # before it are active): S[k][i] is 1 or 0, so that the gathered values are the rows'
    # exactly, and the solve that of the problem of the active rows alone.
    slots, before, S = min(n, MAX_ROWS), ca.SX(0.0), []
    for i in range(n):
        S.append([active[i] * (before == k) for k in range(slots)])
        before += active[i]

    def gather(x: Any) -> list[Any]:
        return [sum(S[i][k] * x[i] for i in range(n)) for k in range(slots)]

    rows_of = [gather(delassus[:n, j]) for j in range(n)]  # D[:, j] gathered, per column j
    D = ca.SX(slots, slots)
    for k in range(slots):
        column = [rows_of[j][k] for j in range(n)]  # D[row of slot k, :]
        for slot, value in enumerate(gather(column)):
            D[k, slot] = value
    solved, w_slots, residual = active_set_terms(
        D, ca.vertcat(*gather(b)), ca.vertcat(*gather(guess)), ca.vertcat(*gather(active))
    )
    impulses = ca.vertcat(*(sum(S[i][k] * solved[k] for k in range(slots)) for i in range(n)))
    w = ca.vertcat(*(sum(S[i][k] * w_slots[k] for k in range(slots)) for i in range(n)))
    h, theta = scalars[0], scalars[1]
    # More active rows than slots, or impulses the energy guard refuses: not solved here.
    residual = ca.if_else(before > slots, np.inf, residual)
    if rules.newton_law == "closing" and any(elastic):  # the energy guard, on the rows of A
        u_plus = w - rebound - closure
        gain = impulse_energy_gain(_casadi_ops(), impulses, J @ v_free, u_plus, J @ v, theta)
        guarded = ca.logic_and(
            ca.sum1(active * (rebound != 0.0)) > 0.0, gains_energy(gain, kinetic)
        )
        residual = ca.if_else(guarded, np.inf, residual)
    v_next = v_free + Winv_Jt @ impulses
    q_next = q + theta_displacement(v, v_next, h, theta)
    bits = ca.DM([2.0**i for i in range(n)])
    impact = is_impact(impulses, activation, u_minus)
    masks = (ca.dot(bits, x) for x in (active, impulses > 0.0, impact))
    outputs = ca.vertcat(impulses, w, residual, *masks, v_next, q_next)
    inputs = [terms, q, v, rows_t, u_minus, activation, scalars, kinetic]
    names = ["terms", "q", "v", "J_t", "u", "activation", "scalars", "kinetic"]
    return ca.Function("several_row_step", inputs, [outputs], names, ["step"])


def _casadi_ops() -> ArrayOps:
    """The shared rules' operations on casadi's symbols."""
    import casadi as ca

    return ArrayOps(ca.if_else, ca.logic_and, ca.logic_or, ca.dot)


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
