r"""Coulomb friction at velocity level as a fixed point of proxsuite QPs (Tresca iterations).

The Coulomb problem of :mod:`ucontrol.solvers.coulomb_problem` is not the optimality system of
any convex QP: the friction bound :math:`\mu P_n` depends on the unknown normal impulse. With the
bound frozen at thresholds :math:`s_a` it becomes Tresca's problem, which is a convex QP
(Haslinger's method; Acary & Brogliato 2008, §13.4):

.. math:: \min_P \tfrac12 P^T D P + b^T P \quad \text{s.t.} \quad P_{n,a} \ge 0, \quad
          P_{t,a} \in s_a \mathcal{D}_a,

:math:`\mathcal{D}_a` the unit interval :math:`[-1, 1]` for a planar contact (a box constraint)
and, for a spatial one, a polygon of ``facets`` facets tangent to the unit disk (linear
inequalities :math:`c_k \cdot P_t \le s_a`; a square by default). One facet is turned at every
iteration to face the current tangential impulse, so that where a contact slides its impulse
ends on the disk itself, not on the polygon; the polish (below) then makes it exact.

0. **Warm start, no QP.** From the second solve of a contact layout on, the last solution is
   polished first (step 3) on the new problem: successive steps of a time-stepping run change
   the problem little, and the polish reaches the residual tolerance from there in one or two
   exact solves or Newton iterations, without a QP. On layouts of a few contacts (at most
   :data:`~ucontrol.solvers.compiled_coulomb_newton.MAX_ROWS` rows) the Newton steps run
   compiled first (:mod:`ucontrol.solvers.compiled_coulomb_newton`); the numpy polish follows
   only where they leave the residual above the tolerance. The solve ends there unless it left a
   contact at its friction bound sliding slower than the tolerance (a block at the friction
   angle: sliding at that speed also satisfies Coulomb's law, and a warm start would keep the
   creep of round-off going step after step), which the fixed point below solves again.

:class:`ProxsuiteCoulombSolver` then iterates

1. solve Tresca's QP for the thresholds :math:`s` (proxsuite, warm-started);
2. measure the natural-map residual of the *true* Coulomb problem; stop when it is at most
   ``residual_tolerance``;
3. polish (when the residual exceeds
   :data:`~ucontrol.solvers.lcp_refinement.POLISH_THRESHOLD`, as for the frictionless LCP):
   semismooth Newton iterations on the Alart–Curnier function from the QP's impulses, kept
   while the residual decreases; where the QP found the right contact statuses this brings the
   residual to round-off, which makes friction impulses exact and a sliding block's
   acceleration exact to ~1e-12;
4. :math:`s \leftarrow s + \omega (\mu P_n - s)` (:math:`\omega = 1`, halved whenever two
   successive updates point in opposite directions) and facets turned; repeat.

The first solve of a contact layout starts from unbounded friction (:math:`s = \infty`: the
sticking problem, solved in one QP wherever the contacts stick; from :math:`s = 0`, the
frictionless problem, if that QP is unbounded); later ones start from the last
solution of the same layout. Where that start is far from the solution — a tangential impact
after sliding (Painlevé's paradox), whose solution is a sticking impulse far above the sliding
ones — the relaxed fixed point and the polish (step 3) reach it from there; a restart from
:math:`s = \infty` is not needed (it changed no solved result in 300 random warm-started
two-row problems, and without the polish it left more of them unsolved: docs/testing.md).

**Bilateral rows** (:attr:`CoulombProblem.equalities`, a closed chain's loop closures): their
impulses are free in sign, so each Tresca QP leaves them unbounded and its optimality system
holds :math:`u_b = D_{b\cdot} P + b_b = 0` exactly as in the frictionless mixed problem; the
polish treats them as always sticking rows (:math:`u_b = 0`, :math:`P_b` free), the
Alart–Curnier function holds :math:`\rho_b u_b` on them.

The fixed point converges for moderate friction and conditioning; the solve reports
``"solved"`` only when the residual is within ``residual_tolerance``, otherwise
``"max_iterations_reached"`` (or ``"stalled"`` when the thresholds stopped moving) and the
caller decides (error or warning).
"""

from __future__ import annotations

import time

import numpy as np
from numpy.typing import NDArray

from ucontrol._validation import as_positive
from ucontrol.exceptions import InvalidParameterError
from ucontrol.solvers.alart_curnier import AlartCurnier, solve_square
from ucontrol.solvers.banded_delassus import BANDED_SIZE, status_polish
from ucontrol.solvers.compiled_coulomb_newton import MARGIN, compiled_newton
from ucontrol.solvers.contact_solution import ContactSolution
from ucontrol.solvers.coulomb_problem import CoulombProblem, tangential_norms
from ucontrol.solvers.lcp_refinement import POLISH_THRESHOLD
from ucontrol.solvers.proxsuite_qp import INFINITY, QP_SOLVED, WarmStartedQP
from ucontrol.solvers.single_contact_coulomb import solve_single_contact

Vector = NDArray[np.float64]

#: Smallest relaxation factor of the threshold update.
MIN_RELAXATION = 1.0 / 16.0
#: Exact solves on guessed contact statuses per polish (each turns the sliding directions).
STATUS_PASSES = 1
#: Newton iterations of the polish per fixed-point iteration.
NEWTON_ITERATIONS = 20
#: The polish stops at a natural-map residual of this times the largest entry of b in
#: absolute value (or at POLISH_THRESHOLD, the smaller).
ROUND_OFF = 1e-14


class ProxsuiteCoulombSolver:
    """Solve Coulomb contact problems by Tresca fixed-point iterations of proxsuite QPs.

    Args:
        residual_tolerance: Natural-map residual of the Coulomb problem accepted as solved,
            in [m/s].
        max_iter: Cap on the fixed-point iterations (Tresca QPs) per solve.
        eps_abs: Absolute tolerance of proxsuite for each Tresca QP, in [m/s].
        qp_max_iter: Iteration cap of proxsuite for each Tresca QP.
        facets: Facets of the polygon that stands for the friction disk of spatial contacts.
        polish: Refine each iterate by exact solves on the contact statuses it suggests and
            semismooth Newton iterations (step 3 of the module docstring).
        compiled_newton: Polish the last solution of a small layout by the compiled Newton
            step of :mod:`ucontrol.solvers.compiled_coulomb_newton` first (step 0 of the
            module docstring); where it does not solve, or nothing compiles, the numpy polish
            runs as without it.
        banded: Polish the last solution of a problem whose Delassus matrix is banded by
            status solves on its band first (:mod:`ucontrol.solvers.banded_delassus`); the
            numpy polish runs after them only where they leave the residual above
            :data:`~ucontrol.solvers.lcp_refinement.POLISH_THRESHOLD`.
    """

    name = "proxsuite-tresca"
    #: Solves problems with bilateral rows (:attr:`CoulombProblem.equalities`).
    bilateral_rows = True

    def __init__(
        self,
        *,
        residual_tolerance: float = 1e-8,
        max_iter: int = 100,
        eps_abs: float = 1e-10,
        qp_max_iter: int = 5000,
        facets: int = 4,
        polish: bool = True,
        compiled_newton: bool = True,
        banded: bool = True,
    ) -> None:
        self.residual_tolerance = as_positive("residual_tolerance", residual_tolerance)
        self.max_iter = int(as_positive("max_iter", max_iter))
        if int(facets) < 3:
            raise InvalidParameterError("facets", facets, ">= 3")
        self.facets = int(facets)
        self.polish = polish
        self.compiled_newton = compiled_newton
        self.banded = banded
        self._qp = WarmStartedQP(eps_abs=eps_abs, max_iter=qp_max_iter, bounds_change=True)
        angles = 2.0 * np.pi * np.arange(self.facets) / self.facets
        self._facet_angles = np.column_stack((np.cos(angles), np.sin(angles)))  # (facets, 2)
        self._guesses: dict[bytes, Vector] = {}

    def reset(self) -> None:
        """Forget the warm starts (the QPs' and the last solutions): solve as a new solver."""
        self._qp.reset()
        self._guesses.clear()

    def solve_coulomb(self, problem: CoulombProblem) -> ContactSolution:
        """Impulses solving ``problem`` to ``residual_tolerance``, if it is reached.

        Args:
            problem: The contact problem (D, b, friction coefficients, layout).
        """
        start = time.perf_counter()
        m = problem.m
        key = problem.tangents.tobytes() + problem.equalities.to_bytes(4, "little")
        if m == 1 and problem.equalities == 0:  # one contact: its statuses enumerated
            single = solve_single_contact(problem)
            if single is not None:
                single_u = problem.velocity(single)
                residual = problem.residual(single, single_u)
                if residual <= self.residual_tolerance:
                    self._guesses[key] = single
                    elapsed = time.perf_counter() - start
                    return ContactSolution(single, single_u, "solved", 0, residual, elapsed)
        guess = self._guesses.get(key)
        best_P, best_u, best = np.zeros(problem.size), problem.b, np.inf
        qp_iterations, polished, status, outer = 0, False, "", 0
        newton = (
            compiled_newton(problem.tangents.tobytes(), problem.equalities)
            if self.polish and self.compiled_newton
            else None
        )
        if newton is not None and guess is not None:  # step 0, compiled: Newton from the guess
            # Down to the round-off floor (target 0: until a step no longer lowers the residual),
            # below the numpy polish's residuals on Solo-12's feet (docs/benchmarks.md).
            fast = newton.polish(problem, guess, NEWTON_ITERATIONS, 0.0, self.residual_tolerance)
            if fast is not None and fast[2] <= self.residual_tolerance and not fast[3]:
                self._guesses[key] = fast[0]
                elapsed = time.perf_counter() - start
                return ContactSolution(fast[0], fast[1], "solved", 0, fast[2], elapsed, True)
        if guess is not None and self.polish:  # step 0: polish the last solution, no QP
            best_u = problem.velocity(guess)
            best_P, best = guess, problem.residual(guess, best_u)
            by_band = None
            if self.banded and problem.size >= BANDED_SIZE:  # O(n) status solves
                by_band = status_polish(problem, best_P, best_u, best, _polish_target(problem))
            if by_band:
                best_P, best_u, best, polished = by_band
            if not by_band or best > POLISH_THRESHOLD:
                best_P, best_u, best, polished = _polish(problem, best_P, best_u, best)
            if _marginal(problem, best_P, best_u, self.residual_tolerance):
                best = np.inf  # solved again by the fixed point, which prefers sticking
        if best > self.residual_tolerance:
            free = -problem.tangential(problem.b)
            thresholds, directions = _unbounded(problem, free)
            if guess is not None:
                thresholds = problem.mu * np.maximum(guess[:m], 0.0)
                directions = _directions(problem.tangential(guess), free)
        relaxation, previous_step = 1.0, np.zeros(m)
        while best > self.residual_tolerance and outer < self.max_iter:
            outer += 1
            P, iterations, qp_solved = self._tresca(problem, thresholds, directions)
            qp_iterations += iterations
            if not qp_solved and thresholds.max(initial=0.0) >= INFINITY:
                # The sticking problem can be unbounded (redundant contacts whose b leaves the
                # range of D): start from the frictionless impulses instead (s = 0).
                thresholds = np.zeros(m)
                continue
            u = problem.velocity(P)
            candidate = (P, u, problem.residual(P, u), False)
            if self.polish and candidate[2] > POLISH_THRESHOLD:
                candidate = _polish(problem, *candidate[:3])
                polished = polished or candidate[3]
            if candidate[2] < best:
                best_P, best_u, best = candidate[:3]
            if best <= self.residual_tolerance:
                break
            step = problem.mu * P[:m] - thresholds  # the Tresca map, from the QP's impulses
            stalled = np.max(np.abs(step), initial=0.0) <= 1e-15 * (1.0 + np.max(thresholds))
            if stalled:
                status = "stalled"
                break
            if thresholds.max(initial=0.0) >= INFINITY:  # from unbounded friction
                thresholds, previous_step = problem.mu * P[:m], np.zeros(m)
            else:
                if step @ previous_step < 0.0:  # oscillation: damp
                    relaxation = max(0.5 * relaxation, MIN_RELAXATION)
                thresholds = thresholds + relaxation * step
                previous_step = step
            directions = _directions(problem.tangential(P), -problem.tangential(u), directions)
        inside = problem.within_cones(best_P)  # a tolerance's excess over the cones removed
        if inside is not best_P:
            best_P, best_u = inside, problem.velocity(inside)
            best = problem.residual(best_P, best_u)
        self._guesses[key] = best_P
        if best <= self.residual_tolerance:
            status = "solved"
        return ContactSolution(
            best_P,
            best_u,
            status or "max_iterations_reached",
            qp_iterations,
            best,
            time.perf_counter() - start,
            polished,
            outer,
        )

    def _tresca(
        self, problem: CoulombProblem, thresholds: Vector, directions: Vector
    ) -> tuple[Vector, int, bool]:
        """Solve Tresca's QP for ``thresholds`` (m,).

        Returns:
            The impulses (r,), proxsuite's iterations, and whether proxsuite solved the QP.
        """
        m, size = problem.m, problem.size
        lower = np.full(size + 1, -INFINITY)  # last entry: sink of the missing tangent rows
        upper = np.full(size + 1, INFINITY)
        lower[:m] = 0.0
        planar = problem.tangents == 1
        rows = problem.tangent_rows[planar, 0]
        lower[rows] = -thresholds[planar]
        upper[rows] = thresholds[planar]
        C = u = None
        if problem.spatial:
            spatial = np.flatnonzero(problem.tangents == 2)
            # Facet normals c_k = R(direction) (cos 2πk/N, sin 2πk/N), shape (n_s, facets, 2).
            cos, sin = directions[spatial, 0, None], directions[spatial, 1, None]
            fx, fy = self._facet_angles[:, 0], self._facet_angles[:, 1]
            normals = np.stack((cos * fx - sin * fy, sin * fx + cos * fy), axis=-1)
            n_in = spatial.size * self.facets
            C = np.zeros((n_in, size))
            facet_rows = np.arange(n_in).reshape(spatial.size, self.facets)
            tangent_rows = problem.tangent_rows[spatial]
            C[facet_rows, tangent_rows[:, 0, None]] = normals[..., 0]
            C[facet_rows, tangent_rows[:, 1, None]] = normals[..., 1]
            u = np.repeat(thresholds[spatial], self.facets)
        results = self._qp.solve(
            problem.D,
            problem.b,
            C,
            None if C is None else np.full(C.shape[0], -INFINITY),
            u,
            lower[:size],
            upper[:size],
        )
        P = np.array(results.x)
        P[:m] = np.maximum(P[:m], 0.0)
        return P, int(results.info.iter), results.info.status == QP_SOLVED


def _marginal(problem: CoulombProblem, P: Vector, u: Vector, tolerance: float) -> bool:
    """Whether a contact slides slower than ``tolerance`` [m/s] with friction at its bound."""
    if problem.m == 0:
        return False
    speed = tangential_norms(problem.tangential(u))
    bound = problem.mu * P[: problem.m]
    at_bound = tangential_norms(problem.tangential(P)) >= (1.0 - MARGIN) * bound
    return bool(np.any((speed > 0.0) & (speed <= tolerance) & (bound > 0.0) & at_bound))


def _unbounded(problem: CoulombProblem, free: Vector) -> tuple[Vector, Vector]:
    """Thresholds (m,) of unbounded friction (the sticking problem), facets facing ``free``."""
    return np.full(problem.m, INFINITY), _directions(np.zeros((problem.m, 2)), free)


def _directions(
    P_t: Vector, fallback: Vector, previous: Vector | None = None, floor: float = 1e-300
) -> Vector:
    """Unit tangential directions (m, 2): of ``P_t`` where non-zero, else of ``fallback``.

    Where both vanish, the ``previous`` direction (or (1, 0)) is kept.
    """
    directions = np.zeros_like(P_t)
    directions[:, 0] = 1.0
    if previous is not None:
        directions[:] = previous
    for vectors in (fallback, P_t):  # P_t last: it wins where both are defined
        norms = tangential_norms(vectors)
        defined = norms > floor
        directions[defined] = vectors[defined] / norms[defined, None]
    return directions


def _polish(
    problem: CoulombProblem, P: Vector, u: Vector, residual: float
) -> tuple[Vector, Vector, float, bool]:
    r"""Refine (P, u): exact solves on guessed contact statuses, then semismooth Newton.

    First, up to :data:`STATUS_PASSES` times, the statuses the natural map suggests (separate,
    stick, slide in the direction of :math:`-u_t`) are imposed and their linear equations
    solved directly (:func:`_solve_on_statuses`): exact in one pass where the statuses and
    directions are right, also with redundant contacts. Then semismooth Newton iterations on
    the Alart–Curnier function (:meth:`AlartCurnier.newton`) turn the sliding directions. Each
    candidate is kept only if its natural-map residual is lower.

    Returns:
        The best impulses (r,), their velocities (r,), natural-map residual in [m/s], and
        whether the polish improved on ``P``.
    """
    improved = False
    target = _polish_target(problem)
    for _ in range(STATUS_PASSES):
        candidate = _solve_on_statuses(problem, P, u)
        if candidate is None:
            break
        candidate_u = problem.velocity(candidate)
        candidate_residual = problem.residual(candidate, candidate_u)
        if not candidate_residual < residual:
            break
        P, u, residual, improved = candidate, candidate_u, candidate_residual, True
        if residual <= target:
            return P, u, residual, improved
    P, u, residual, newton_improved = AlartCurnier(problem).newton(
        P, u, residual, NEWTON_ITERATIONS, target
    )
    return P, u, residual, improved or newton_improved


def _polish_target(problem: CoulombProblem) -> float:
    """Natural-map residual in [m/s] at which a polish stops (:data:`ROUND_OFF`)."""
    return min(POLISH_THRESHOLD, ROUND_OFF * float(np.abs(problem.b).max(initial=0.0)))


def _solve_on_statuses(problem: CoulombProblem, P: Vector, u: Vector) -> Vector | None:
    r"""Impulses satisfying exactly the equations of the statuses suggested by (P, u).

    With :math:`z = \sigma P - \hat u` (the natural map's argument), a contact whose z lies in
    the polar cone separates (:math:`P_a = 0`), one inside the cone sticks (:math:`u_a = 0`)
    and one outside slides (:math:`u_n = 0, P_t = \mu P_n d`) with d the direction of
    :math:`-u_t` (of :math:`z_t` where :math:`u_t = 0`). The equations are solved directly, by
    least squares where redundant contacts make them singular. Returns None when that gives a
    negative normal impulse.
    """
    m, size, mu = problem.m, problem.size, problem.mu
    sigma = problem.normal_scale
    u_t = problem.tangential(u)
    norm_u_t = tangential_norms(u_t)
    z_n = sigma * P[:m] - (u[:m] + mu * norm_u_t)
    z_t = sigma[:, None] * problem.tangential(P) - u_t
    t = tangential_norms(z_t)
    separated = mu * t <= -z_n
    stick = ~separated & ((problem.tangents == 0) | (t < mu * z_n))
    slide = np.flatnonzero(~separated & ~stick)
    stick_contacts = np.flatnonzero(stick)
    stick_rows = np.concatenate((stick_contacts, problem.tangent_rows[stick_contacts].ravel()))
    stick_rows = np.concatenate((stick_rows[stick_rows < size], problem.equality_rows))
    moving = norm_u_t[slide] > 0.0
    d = np.where(
        moving[:, None],
        -u_t[slide] / np.where(moving, norm_u_t[slide], 1.0)[:, None],
        z_t[slide] / t[slide, None],
    )
    E_slide = np.zeros((size + 1, slide.size))  # last row: sink of the missing tangent rows
    columns = np.arange(slide.size)
    rows = problem.tangent_rows[slide]
    E_slide[slide, columns] = 1.0
    E_slide[rows[:, 0], columns] = mu[slide] * d[:, 0]
    E_slide[rows[:, 1], columns] += mu[slide] * d[:, 1]  # += : planar ones hit the sink row
    E_slide = E_slide[:size]
    equations = np.concatenate((stick_rows, slide))
    if equations.size == 0:
        return np.zeros(size)
    D_rows = problem.D[equations]
    A = np.hstack((D_rows[:, stick_rows], D_rows @ E_slide))
    rhs = -problem.b[equations]
    y = solve_square(A, rhs)
    candidate = _impulses(y, stick_rows, E_slide, size)
    if np.any(candidate[:m] < 0.0):
        # The minimum-norm solution of singular equations may have negative normal impulses
        # where non-negative ones exist: bounded least squares on the normal unknowns.
        normal = np.concatenate((stick_rows < m, np.ones(slide.size, dtype=bool)))
        lower = np.where(normal, 0.0, -np.inf)
        import scipy.optimize  # rare: loaded only when needed

        y = scipy.optimize.lsq_linear(A, rhs, bounds=(lower, np.inf), method="bvls").x
        candidate = _impulses(y, stick_rows, E_slide, size)
    if np.any(candidate[:m] < -1e-12 * (1.0 + np.abs(candidate[:m]).max())):
        return None
    candidate[:m] = np.maximum(candidate[:m], 0.0)
    return candidate


def _impulses(y: Vector, stick_rows: NDArray[np.intp], E_slide: Vector, size: int) -> Vector:
    """Impulses (r,) from the unknowns y of :func:`_solve_on_statuses`."""
    impulses = E_slide @ y[stick_rows.size :]
    impulses[stick_rows] += y[: stick_rows.size]
    return impulses
