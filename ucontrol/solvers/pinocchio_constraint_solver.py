r"""Pinocchio 4.1's ADMM and PGS constraint solvers, as a reference for our contact solver.

Two entry points, both for verification and benchmarks (the plant uses
:class:`~ucontrol.solvers.proxsuite_lcp.ProxsuiteLCPSolver` and
:class:`~ucontrol.solvers.proxsuite_coulomb.ProxsuiteCoulombSolver` by default):

- :class:`PinocchioContactSolver` solves the same problems as our solvers from the Delassus
  matrix D and the term b of one Moreau–Jean step, with ``pin.ADMMConstraintSolver`` or
  ``pin.PGSConstraintSolver``: the frictionless LCP :math:`0 \le P \perp D P + b \ge 0`
  (:meth:`~PinocchioContactSolver.solve`) and the Coulomb problem of
  :class:`~ucontrol.solvers.coulomb_problem.CoulombProblem`
  (:meth:`~PinocchioContactSolver.solve_coulomb`, friction set on each
  ``PointContactConstraintModel``, ``solve_ncp = True``). It can replace our solvers in
  :class:`~ucontrol.integrators.MoreauJean` (scene key ``contact_solver``).
- :class:`PinocchioStepper` (and :func:`pinocchio_step`) runs one whole velocity-level step
  "the Pinocchio way": ``aba`` for the free velocity, ``crba`` in the WORLD convention,
  ``PointContactConstraintModel`` contacts, the Delassus operator of a
  ``ConstraintCholeskyDecomposition``, the ADMM or PGS solve and ``aba`` again for
  :math:`v_{k+1}` — what a Pinocchio user would write.

**Which Pinocchio constraint.** Pinocchio 4.1 has no one-dimensional unilateral point contact:
``PointContactConstraintModel`` is a 3D contact whose impulse lives in a Coulomb cone
(``CoulombFrictionCone``, axis = local z) and whose velocity lives in the dual cone. With the
friction coefficient set to 0 the cone is the half-line :math:`\{P_t = 0, P_n \ge 0\}` and its
dual the half-space :math:`\{u_n \ge 0\}` (tangential velocities free, De Saxcé correction
:math:`\mu \|u_t\| = 0`), so the conic problem is exactly the frictionless LCP in the normal
components. We therefore use one frictionless ``PointContactConstraintModel`` per contact:

- in :class:`PinocchioContactSolver`, the m normal rows are embedded in a 3m problem whose
  local z components carry D and b, the tangential block is the identity and the tangential
  drift is 0 (so the tangential impulses are 0 and do not couple). With friction, the
  tangential rows of contact a go to its local x (and y) components, its model gets
  ``setFriction(mu_a)``, and the local y of a planar contact keeps the uncoupled identity row
  (its impulse is then 0: a planar Coulomb law);
- in :class:`PinocchioStepper`, joint 1 is the universe with a placement whose z axis is the
  plane normal and joint 2 is the contact frame's parent joint with the frame's placement; the
  constraint velocity is then (velocity of point 2 - velocity of point 1) in the axes of
  placement 1, whose z row is :math:`n^T J_{lin}(F)` — the row of our
  :class:`~ucontrol.contact.constraint_set.ConstraintSet`.

**Facts of pin 4.1 relied on** (DESIGN §6, checked here):

- ADMM updates the damping of the Delassus operator it is given in place, so a dense operator is
  rebuilt for every solve.
- The ``ConstraintCholeskyDecomposition`` of redundant contacts is singular without
  regularization (NaN impulses); PGS needs a small compliance (default 1e-10, passed as the
  decomposition's ``mu``), ADMM does not (it damps the operator itself).
- PGS's stopping test evaluates each contact's complementarity right after that contact's own
  update, inside the sweep, so with frictionless contacts it can be met after the first sweep
  although later updates in that sweep changed the earlier contacts' velocities. On
  :math:`D = [[2, 1], [1, 2]]`, :math:`b = (-1, -1)` it returns :math:`P = (0.5, 0.25)` (one
  Gauss–Seidel sweep; the solution is :math:`(1/3, 1/3)`) with ``converged``,
  ``iterations == 0`` and ``complementarity == 0``. A ``solve`` call starts from the guess of
  ``result.setConstraintImpulseGuess``, so :class:`PinocchioContactSolver` repeats
  warm-started solves until *our* complementarity residual is below the tolerance;
  :class:`PinocchioStepper` does so only when ``pgs_until_solved`` is set (by default it is the
  loop a Pinocchio user writes).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol._validation import as_in_interval, as_positive, as_vector
from ucontrol.contact.point_contact import PointContact
from ucontrol.contact.tangent_basis import tangent_basis
from ucontrol.exceptions import (
    FrameNotFoundError,
    InvalidParameterError,
    NonFiniteValueError,
    ShapeError,
    SolverError,
)
from ucontrol.model.robot_model import frame_index
from ucontrol.solvers.contact_solution import ContactSolution, complementarity_residual
from ucontrol.solvers.coulomb_problem import CoulombProblem

Vector = NDArray[np.float64]

#: Methods accepted by :class:`PinocchioContactSolver` and :class:`PinocchioStepper`.
METHODS = ("admm", "pgs")

_LWA = pin.LOCAL_WORLD_ALIGNED
_NORMAL = slice(2, None, 3)  # local z components of stacked 3D contacts


def _check_method(method: str) -> str:
    if method not in METHODS:
        raise InvalidParameterError("method", method, f"one of {METHODS}")
    return method


def _check_compliance(compliance: float) -> float:
    value = float(compliance)
    if not value >= 0.0:
        raise InvalidParameterError("compliance", compliance, ">= 0")
    return value


def _backend(method: str, size: int, tolerance: float, max_iter: int) -> tuple[Any, Any, Any]:
    """A Pinocchio solver of ``method`` for ``size`` unknowns, its settings and result."""
    if method == "admm":
        solver, settings, result = (
            pin.ADMMConstraintSolver(size),
            pin.ADMMSolverSettings(),
            pin.ADMMSolverResult(),
        )
    else:
        solver, settings, result = (
            pin.PGSConstraintSolver(size),
            pin.PGSSolverSettings(),
            pin.PGSSolverResult(),
        )
    settings.absolute_feasibility_tol = tolerance
    settings.relative_feasibility_tol = tolerance
    settings.absolute_complementarity_tol = tolerance
    settings.relative_complementarity_tol = tolerance
    settings.max_iterations = max_iter
    settings.solve_ncp = True  # De Saxcé's Coulomb NCP, not its convex relaxation
    return solver, settings, result


def _frictionless(contact_model: pin.PointContactConstraintModel) -> pin.ConstraintModel:
    """``contact_model`` with friction 0, wrapped in a generic constraint model."""
    contact_model.setFriction(0.0)
    return pin.ConstraintModel(contact_model)


def _normal_residual(G: Vector, drift: Vector, impulses: Vector) -> float:
    """Natural-map residual of the normal components of a stacked 3D contact problem, [m/s]."""
    velocity = G[_NORMAL] @ impulses + drift[_NORMAL]
    scale = np.diag(G)[_NORMAL]
    return float(np.max(np.abs(np.minimum(scale * impulses[_NORMAL], velocity)), initial=0.0))


def _solve(
    name: str,
    backend: tuple[Any, Any, Any],
    delassus: Any,
    drift: Vector,
    models: Any,
    datas: Any,
    *,
    pgs_until: tuple[Callable[[Vector], float], float, int] | None = None,
) -> tuple[Vector, bool, int]:
    """Run the backend; for PGS with ``pgs_until = (residual, tolerance, max_sweeps)`` sweep.

    PGS is swept again, warm-started, until ``residual(impulses)`` (in [m/s]) is at most
    ``tolerance`` or ``max_sweeps`` sweeps were made.

    Returns:
        The stacked impulses (3m,), whether the backend (or our residual check) converged, and
        the iterations (ADMM) or sweeps (PGS).

    Raises:
        SolverError: Pinocchio raised, or returned non-finite impulses.
    """
    solver, settings, result = backend
    try:
        converged = solver.solve(delassus, drift, models, datas, settings, result)
        impulses = result.retrieveConstraintImpulses()
        iterations = int(result.iterations)
        if pgs_until is not None:
            residual, tolerance, max_sweeps = pgs_until
            iterations += 1  # pin counts PGS sweeps from 0
            converged = residual(impulses) <= tolerance
            while not converged and iterations < max_sweeps and np.all(np.isfinite(impulses)):
                result.setConstraintImpulseGuess(impulses)
                solver.solve(delassus, drift, models, datas, settings, result)
                impulses = result.retrieveConstraintImpulses()
                iterations += int(result.iterations) + 1
                converged = residual(impulses) <= tolerance
    except (RuntimeError, ValueError, ArithmeticError) as error:
        raise SolverError(name, f"raised {error!r}") from error
    if not np.all(np.isfinite(impulses)):
        raise SolverError(name, "non-finite impulses")
    return impulses, bool(converged), iterations


class PinocchioContactSolver:
    r"""Contact problems solved by Pinocchio's ADMM or PGS constraint solver.

    Same interfaces as :class:`~ucontrol.solvers.proxsuite_lcp.ProxsuiteLCPSolver` (:meth:`solve`:
    the impulses of :math:`0 \le P \perp D P + b \ge 0`) and
    :class:`~ucontrol.solvers.proxsuite_coulomb.ProxsuiteCoulombSolver` (:meth:`solve_coulomb`).
    Each contact is a 3D ``PointContactConstraintModel`` cone whose local z row carries the
    normal row of (D, b) and whose local x, y rows carry its tangential rows, or an uncoupled
    identity (see the module docstring). Solver objects are kept per size. PGS is swept again,
    warm-started, until our residual is below ``tolerance`` (frictionless) or
    ``residual_tolerance`` (Coulomb): pin's own PGS stopping test is not reliable, see the
    module docstring.

    Args:
        method: ``"admm"`` or ``"pgs"``.
        tolerance: Absolute and relative feasibility and complementarity tolerance of the
            backend, and bound on our frictionless residual for PGS, in [m/s].
        max_iter: Iteration cap of ADMM, or cap on the total PGS sweeps.
        compliance: Added to the diagonal of D in [m/s per N s], >= 0.
        residual_tolerance: Natural-map residual of a Coulomb problem accepted as solved, in
            [m/s] (:meth:`solve_coulomb`).
    """

    def __init__(
        self,
        method: str = "admm",
        *,
        tolerance: float = 1e-12,
        max_iter: int = 10_000,
        compliance: float = 0.0,
        residual_tolerance: float = 1e-8,
    ) -> None:
        self.method = _check_method(method)
        self.name = f"pinocchio-{method}"
        self.tolerance = as_positive("tolerance", tolerance)
        self.max_iter = int(as_positive("max_iter", max_iter))
        self.compliance = _check_compliance(compliance)
        self.residual_tolerance = as_positive("residual_tolerance", residual_tolerance)
        self._empty_model = pin.Model()
        self._problems: dict[tuple[int, bool], tuple[Any, ...]] = {}

    def reset(self) -> None:
        """Drop the backends and their results: the next solves start as a new solver's."""
        self._problems.clear()

    def _problem(self, m: int, friction: bool = False) -> tuple[Any, ...]:
        """Constraint models, datas, backend and buffers for m contacts.

        The frictionless problems keep friction 0 on their models; the Coulomb ones (own
        models, ``friction`` True) get the coefficients of each solve.
        """
        problem = self._problems.get((m, friction))
        if problem is None:
            models = pin.StdVec_ConstraintModel()
            datas = pin.StdVec_ConstraintData()
            for _ in range(m):
                models.append(_frictionless(pin.PointContactConstraintModel(self._empty_model)))
                datas.append(models[-1].createData())
            backend = _backend(self.method, 3 * m, self.tolerance, self.max_iter)
            G = np.eye(3 * m)  # tangential block: identity, uncoupled
            g = np.zeros(3 * m)  # tangential drift: 0
            problem = (models, datas, backend, G, g)
            self._problems[m, friction] = problem
        return problem

    def _run(
        self,
        G: Vector,
        g: Vector,
        models: Any,
        datas: Any,
        backend: tuple[Any, Any, Any],
        residual: Callable[[Vector], float],
        tolerance: float,
    ) -> tuple[Vector, bool, int]:
        """Solve the stacked 3D problem (G, g): impulses (3m,), converged, iterations."""
        delassus = pin.DelassusOperatorDense(G)  # fresh: ADMM changes its damping in place
        if self.compliance > 0.0:
            delassus.updateCompliance(self.compliance)
        pgs_until = (residual, tolerance, self.max_iter) if self.method == "pgs" else None
        return _solve(self.name, backend, delassus, g, models, datas, pgs_until=pgs_until)

    def solve(self, D: NDArray[np.float64], b: NDArray[np.float64]) -> ContactSolution:
        """Impulses P >= 0 with D P + b >= 0 and P · (D P + b) = 0.

        Args:
            D: Delassus matrix, symmetric positive semidefinite, shape (m, m), [m/s per N s].
            b: Free constraint velocity plus restitution term in [m/s], shape (m,).

        Raises:
            ShapeError: ``b`` is not a vector, or ``D`` is not (m, m) for ``b`` of shape (m,).
            NonFiniteValueError: ``D`` or ``b`` holds NaN or infinity (flat indices).
            SolverError: Pinocchio raised, or returned non-finite impulses.
        """
        start = time.perf_counter()
        b = as_vector("b", b)
        D = np.asarray(D, dtype=float)
        m = b.shape[0]
        if D.shape != (m, m):
            raise ShapeError("D", (m, m), D.shape)
        bad = np.flatnonzero(~np.isfinite(D))
        if bad.size:
            raise NonFiniteValueError("D", D, bad.tolist())
        if m == 0:
            return ContactSolution(
                impulses=np.zeros(0),
                velocity=np.zeros(0),
                status="solved",
                iterations=0,
                residual=0.0,
                solve_time_s=time.perf_counter() - start,
            )
        models, datas, backend, G, g = self._problem(m)
        G[_NORMAL, _NORMAL] = D
        g[_NORMAL] = b
        residual = partial(_normal_residual, G, g)
        stacked, converged, iterations = self._run(
            G, g, models, datas, backend, residual, self.tolerance
        )
        impulses = np.maximum(stacked[_NORMAL], 0.0)
        return ContactSolution(
            impulses=impulses,
            velocity=D @ impulses + b,
            status="solved" if converged else "max_iterations_reached",
            iterations=iterations,
            residual=complementarity_residual(D, b, impulses),
            solve_time_s=time.perf_counter() - start,
        )

    def solve_coulomb(self, problem: CoulombProblem) -> ContactSolution:
        """Impulses of the Coulomb problem ``problem``, by ADMM (``solve_ncp``) or PGS.

        The status is ``"solved"`` when our natural-map residual is within
        ``residual_tolerance``, otherwise ``"max_iterations_reached"`` (the backend did not
        converge) or ``"inaccurate"`` (it converged by its own criteria only).

        Args:
            problem: The contact problem (D, b, friction coefficients, layout).

        Raises:
            NonFiniteValueError: ``problem.D`` holds NaN or infinity (flat indices).
            SolverError: Pinocchio raised, or returned non-finite impulses.
        """
        start = time.perf_counter()
        m = problem.m
        bad = np.flatnonzero(~np.isfinite(problem.D))
        if bad.size:
            raise NonFiniteValueError("D", problem.D, bad.tolist())
        models, datas, backend, G, g = self._problem(m, friction=True)
        for constraint_model, mu in zip(models, problem.mu.tolist(), strict=True):
            constraint_model.extract().setFriction(mu)
        positions = _local_positions(problem)
        G[:] = 0.0
        G[np.diag_indices(3 * m)] = 1.0  # uncoupled identity where no row of ours goes
        G[np.ix_(positions, positions)] = problem.D
        g[:] = 0.0
        g[positions] = problem.b

        def residual(stacked: Vector) -> float:
            return problem.residual(stacked[positions])

        stacked, converged, iterations = self._run(
            G, g, models, datas, backend, residual, self.residual_tolerance
        )
        impulses = stacked[positions]
        impulses[:m] = np.maximum(impulses[:m], 0.0)
        velocity = problem.velocity(impulses)
        value = problem.residual(impulses, velocity)
        if value <= self.residual_tolerance:
            status = "solved"
        else:
            status = "inaccurate" if converged else "max_iterations_reached"
        return ContactSolution(
            impulses=impulses,
            velocity=velocity,
            status=status,
            iterations=iterations,
            residual=value,
            solve_time_s=time.perf_counter() - start,
        )


@dataclass(frozen=True)
class PinocchioStepOutcome:
    """The result of one step of :class:`PinocchioStepper`.

    Attributes:
        q: Configuration at the end of the step, shape (nq,).
        v: Velocity at the end of the step, shape (nv,).
        impulse: Normal impulse of each contact over the step in [N s], shape (n,).
        active: Which contacts were in the active set, shape (n,).
        converged: Whether the backend reported convergence (True without active contacts).
        iterations: ADMM iterations or PGS sweeps (0 without active contacts).
    """

    q: Vector
    v: Vector
    impulse: Vector
    active: NDArray[np.bool_]
    converged: bool
    iterations: int


class PinocchioStepper:
    r"""One frictionless Moreau–Jean step written with Pinocchio's own contact machinery.

    Per step, with :math:`h` = ``dt``:

    1. ``aba`` gives :math:`v_\text{free} = v_k + h M^{-1}(\tau - h(q_k, v_k))`;
    2. ``crba`` (WORLD convention, also the joint placements) and the frame placements give the
       gaps and normal velocities; contact a is active iff :math:`g_a + (h/2) u_a \le 0`, the
       rule of :class:`~ucontrol.integrators.moreau_jean.MoreauJean`;
    3. the active ``PointContactConstraintModel`` are evaluated (``calc``), a
       ``ConstraintCholeskyDecomposition`` is computed and its Delassus operator handed to
       ``ADMMConstraintSolver`` / ``PGSConstraintSolver`` with drift
       :math:`J v_\text{free} + e \odot J_n v_k` (restitution on the normal rows);
    4. :math:`v_{k+1} = v_k + h\,\mathrm{aba}(q_k, v_k, \tau + J^T P / h)` and
       :math:`q_{k+1} = q_k \oplus h((1-\theta) v_k + \theta v_{k+1})`.

    Constraint models are built once per contact (their placements are constant: the normal
    is fixed in the world, the point fixed on the body); the Cholesky decomposition and the
    solver are built once per active set. Joint stops are not modelled.

    Args:
        model: The Pinocchio model.
        contacts: Point contacts against planes (frame, plane, radius, restitution; friction
            is ignored, the step is frictionless).
        dt: Time step h in [s].
        theta: θ of the position update, in [1/2, 1].
        method: ``"admm"`` or ``"pgs"``.
        tolerance: Feasibility and complementarity tolerance of the backend in [m/s].
        max_iter: Iteration cap of the backend (total sweeps with ``pgs_until_solved``).
        compliance: Regularization ``mu`` of the Cholesky decomposition (added to the Delassus
            diagonal) in [m/s per N s]; default 0 for ADMM and 1e-10 for PGS.
        pgs_until_solved: Sweep PGS again, warm-started, until the normal complementarity
            residual is below ``tolerance`` (off: trust pin's stopping test, as a user would).
        data: Pinocchio data buffer to use; default a private one.

    Raises:
        FrameNotFoundError: A contact frame is not in ``model``.
    """

    def __init__(
        self,
        model: pin.Model,
        contacts: Sequence[PointContact],
        *,
        dt: float,
        theta: float = 0.5,
        method: str = "admm",
        tolerance: float = 1e-12,
        max_iter: int = 10_000,
        compliance: float | None = None,
        pgs_until_solved: bool = False,
        data: pin.Data | None = None,
    ) -> None:
        self.model = model
        self.data = data if data is not None else pin.Data(model)
        self.contacts = tuple(contacts)
        self.dt = as_positive("dt", dt)
        self.theta = as_in_interval("theta", theta, 0.5, 1.0)
        self.method = _check_method(method)
        self.name = f"pinocchio-{method}"
        self.tolerance = as_positive("tolerance", tolerance)
        self.max_iter = int(as_positive("max_iter", max_iter))
        default_compliance = 1e-10 if method == "pgs" else 0.0
        self.compliance = _check_compliance(
            default_compliance if compliance is None else compliance
        )
        self.pgs_until_solved = pgs_until_solved and method == "pgs"
        self._frame_ids: list[int] = []
        self._contact_models: list[pin.ConstraintModel] = []
        for contact in self.contacts:
            if not model.existFrame(contact.frame):
                raise FrameNotFoundError(contact.frame, [frame.name for frame in model.frames])
            frame_id = frame_index(model, contact.frame)
            frame = model.frames[frame_id]
            world_placement = pin.SE3(
                _rotation_with_z(contact.surface.normal), contact.surface.point
            )
            self._frame_ids.append(frame_id)
            self._contact_models.append(
                _frictionless(
                    pin.PointContactConstraintModel(
                        model, 0, world_placement, frame.parentJoint, frame.placement
                    )
                )
            )
        self._normals = np.array([c.surface.normal for c in self.contacts]).reshape(-1, 3)
        self._offsets = np.array(
            [c.surface.normal @ c.surface.point + c.radius for c in self.contacts]
        )
        self._restitution = np.array([c.restitution for c in self.contacts], dtype=float)
        self._active_sets: dict[tuple[int, ...], tuple[Any, ...]] = {}

    def _active_set(self, indices: tuple[int, ...]) -> tuple[Any, ...]:
        """Models, datas, Cholesky decomposition and backend of the active set ``indices``."""
        entry = self._active_sets.get(indices)
        if entry is None:
            models = pin.StdVec_ConstraintModel()
            datas = pin.StdVec_ConstraintData()
            for i in indices:
                models.append(self._contact_models[i])
                datas.append(models[-1].createData())
                models[-1].calc(self.model, self.data, datas[-1])
            cholesky = pin.ConstraintCholeskyDecomposition(self.model, self.data, models, datas)
            backend = _backend(self.method, 3 * len(indices), self.tolerance, self.max_iter)
            restitution = self._restitution[list(indices)]
            entry = (models, datas, cholesky, backend, restitution)
            self._active_sets[indices] = entry
        return entry

    def step(self, q: Vector, v: Vector, tau: Vector) -> PinocchioStepOutcome:
        """Advance one step from (q, v) under generalized forces ``tau`` (nv,) in [N m] or [N].

        Raises:
            SolverError: Pinocchio raised, or returned non-finite impulses.
        """
        model, data, h = self.model, self.data, self.dt
        v_free = v + h * pin.aba(model, data, q, v, tau)
        pin.crba(model, data, q, pin.Convention.WORLD)  # M, oMi; data.v comes from aba
        n = len(self.contacts)
        gap = np.empty(n)
        normal_velocity = np.empty(n)
        for i, frame_id in enumerate(self._frame_ids):
            placement = pin.updateFramePlacement(model, data, frame_id)
            gap[i] = self._normals[i] @ placement.translation - self._offsets[i]
            velocity = pin.getFrameVelocity(model, data, frame_id, _LWA).linear
            normal_velocity[i] = self._normals[i] @ velocity
        active = gap + 0.5 * h * normal_velocity <= 0.0
        impulse = np.zeros(n)
        converged, iterations = True, 0
        if active.any():
            indices = tuple(np.flatnonzero(active).tolist())
            models, datas, cholesky, backend, restitution = self._active_set(indices)
            try:
                for constraint_model, constraint_data in zip(models, datas, strict=True):
                    constraint_model.calc(model, data, constraint_data)
                cholesky.compute(model, data, models, datas, self.compliance)
                delassus = cholesky.getDelassusOperatorCholeskyExpression()
                # (3m, nv): pin returns a vector when nv = 1
                J = np.reshape(
                    pin.getConstraintsJacobian(model, data, models, datas), (-1, model.nv)
                )
            except (RuntimeError, ValueError, ArithmeticError) as error:
                raise SolverError(self.name, f"raised {error!r}") from error
            drift = J @ v_free
            drift[_NORMAL] += restitution * normal_velocity[list(indices)]
            pgs_until = None
            if self.pgs_until_solved:
                residual = partial(_normal_residual, delassus.matrix(), drift)
                pgs_until = (residual, self.tolerance, self.max_iter)
            impulses, converged, iterations = _solve(
                self.name, backend, delassus, drift, models, datas, pgs_until=pgs_until
            )
            impulse[list(indices)] = impulses[_NORMAL]
            v_next = v + h * pin.aba(model, data, q, v, tau + J.T @ impulses / h)
        else:
            v_next = v_free
        q_next = pin.integrate(model, q, h * ((1.0 - self.theta) * v + self.theta * v_next))
        return PinocchioStepOutcome(q_next, v_next, impulse, active, converged, iterations)


def pinocchio_step(
    model: pin.Model,
    data: pin.Data,
    q: Vector,
    v: Vector,
    tau: Vector,
    dt: float,
    contacts: Sequence[PointContact],
    **options: Any,
) -> PinocchioStepOutcome:
    """One Moreau–Jean step the Pinocchio way; see :class:`PinocchioStepper`.

    Builds the constraint models and the solver for this call only; loops should keep a
    :class:`PinocchioStepper` instead.

    Args:
        model: The Pinocchio model.
        data: Its data buffer (overwritten).
        q: Configuration, shape (nq,).
        v: Velocity, shape (nv,).
        tau: Generalized forces, shape (nv,), in [N m] or [N].
        dt: Time step in [s].
        contacts: Point contacts against planes.
        **options: ``theta``, ``method``, ``tolerance``, ``max_iter``, ``compliance``,
            ``pgs_until_solved`` of :class:`PinocchioStepper`.

    Returns:
        The step's outcome; ``outcome.v`` is :math:`v_{k+1}`.
    """
    return PinocchioStepper(model, contacts, dt=dt, data=data, **options).step(q, v, tau)


def _local_positions(problem: CoulombProblem) -> NDArray[np.intp]:
    """Where each row of ``problem`` goes in the stacked 3D problem, shape (r,).

    Contact a occupies rows 3a (local x: first tangent), 3a + 1 (local y: second tangent)
    and 3a + 2 (local z: normal).
    """
    m = problem.m
    positions = np.empty(problem.size + 1, dtype=np.intp)  # last entry: sink of missing rows
    positions[:m] = 3 * np.arange(m) + 2
    positions[problem.tangent_rows[:, 0]] = 3 * np.arange(m)
    positions[problem.tangent_rows[:, 1]] = 3 * np.arange(m) + 1
    return positions[: problem.size]


def _rotation_with_z(normal: Vector) -> Vector:
    """A rotation matrix (3, 3) whose third column is the unit vector ``normal``."""
    return np.column_stack((*tangent_basis(normal), normal))
