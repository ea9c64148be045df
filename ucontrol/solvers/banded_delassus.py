r"""Exact solves on contact statuses where the Delassus matrix is banded: linear in the contacts.

A contact couples only the bodies it touches: the Delassus matrix :math:`D = J W^{-1} J^T` of
a chain of bodies touching one after the other (a column of beads, a stack of boxes, a rope
of links on a table) has non-zero blocks only between contacts that share a body. With each
contact's rows kept together (its normal row, then its tangential ones) and the contacts
ordered along the chain, D is a band matrix: for a column of planar beads, each contact's two
rows coupled to the rows of the contact below and above, its half bandwidth is 3 whatever the
length of the column.

**Detection, from the rows' sparsity alone.** The contacts (and each bilateral row) are the
nodes of a graph whose edges are the non-zero blocks of D; the reverse Cuthill–McKee order of
that graph (:func:`scipy.sparse.csgraph.reverse_cuthill_mckee`) numbers the nodes so that
coupled ones are close, and the rows are ordered node after node. The half bandwidth k of D in
that order (at least the size of a node's row group minus one) decides: the band is used from
:data:`BANDED_SIZE` rows on where :math:`k \le r / 8` (:data:`BANDWIDTH_FRACTION`). The order
is a function of the row layout and of D's non-zero pattern, kept for the last few patterns
(:data:`ORDERS`): a change of the pattern, e.g. two contacts that come to share a body, finds
the order again, and a solve never depends on the problems solved before it.

**The solve.** At impulses P with velocities u, the natural map's argument
:math:`z = \sigma P - \hat u` gives each contact's status (the cone of
:mod:`ucontrol.solvers.coulomb_problem`): separating where z lies in the polar cone, sticking
inside the cone, sliding outside it, in the direction :math:`d` of :math:`-u_t` (of
:math:`z_t` where :math:`u_t = 0`). Each status is linear equations in P, one per row:

- separating: :math:`P_i = 0` on the contact's rows;
- sticking, and every bilateral row: :math:`(D P + b)_i = 0`;
- sliding: :math:`(D P + b)_n = 0` on the normal row, :math:`P_t - \mu P_n d = 0` on the
  tangential ones.

Rows of D and local rows within a contact's own group: in the banded order the system has the
band of D, and LAPACK's band LU with partial pivoting (``dgbsv``; the system is not symmetric)
solves it in :math:`O(r k^2)` operations. Statuses are guessed again from the solution and the
system solved again while the natural-map residual decreases (a primal–dual active-set
iteration: where the statuses are right, one solve is exact to round-off; time-stepping's
successive problems keep the last step's statuses almost everywhere), and stops as soon as
the statuses repeat. A singular system (redundant contacts: U's diagonal spread beyond
:data:`~ucontrol.solvers.alart_curnier.LSTSQ_CONDITION`) or a negative normal impulse ends
the iteration with the best impulses so far; the caller's general polish then takes over
where the residual is above its threshold.
"""

from __future__ import annotations

import functools
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from ucontrol.solvers.alart_curnier import LSTSQ_CONDITION
from ucontrol.solvers.coulomb_problem import CoulombProblem, row_groups, tangential_norms

Vector = NDArray[np.float64]

#: Rows from which a banded Delassus matrix is looked for (below, dense solves cost less).
BANDED_SIZE = 64
#: Largest half bandwidth, as a fraction of the rows, solved as a band.
BANDWIDTH_FRACTION = 0.125
#: Cap on the status solves per call.
STATUS_SOLVES = 8
#: Band orders kept, by row layout and non-zero pattern of D.
ORDERS = 16
#: Status of a contact: separating (impulse 0), sticking (velocity 0), sliding (on the cone).
SEPARATE, STICK, SLIDE = 0, 1, 2


class BandOrder(NamedTuple):
    r"""A row order in which a Delassus matrix is banded, and how to gather its band.

    Attributes:
        order: Row of the problem at each position of the band order, shape (r,).
        position: Position of each row of the problem in the band order, shape (r,).
        bandwidth: Half bandwidth k: :math:`D_{ij} = 0` for :math:`|pos_i - pos_j| > k`.
        flat: Flat index into D (r × r) of each entry of LAPACK's general band storage
            (3k + 1, r) of D in the band order (0 where the entry lies outside the matrix or
            in the k rows the factorization fills).
        flat_next: The same for the entry (i + 1, j) of D in the band order, i the storage
            entry's row (clipped at the last row; read only where the row combines with it).
        flat_previous: The same for the entry (i - 1, j).
        valid: Whether each entry of that storage is an entry of D, shape (3k + 1, r).
        band_row: Position (band order) of the matrix row of each storage entry, (3k + 1, r).
    """

    order: NDArray[np.intp]
    position: NDArray[np.intp]
    bandwidth: int
    flat: NDArray[np.intp]
    flat_next: NDArray[np.intp]
    flat_previous: NDArray[np.intp]
    valid: NDArray[np.bool_]
    band_row: NDArray[np.intp]


def band_order(problem: CoulombProblem) -> BandOrder | None:
    """The band order of ``problem``'s D, or None where D is small or not banded enough.

    A function of the row layout and of D's non-zero pattern alone (the last
    :data:`ORDERS` kept), whatever the problems solved before.
    """
    if problem.size < BANDED_SIZE:
        return None
    pattern = np.packbits(problem.D != 0.0).tobytes()
    return _band_order(problem.tangents.tobytes(), problem.equalities, pattern)


def status_polish(
    problem: CoulombProblem, P: Vector, u: Vector, residual: float, target: float
) -> tuple[Vector, Vector, float, bool] | None:
    """Status solves from (P, u) while they lower the natural-map residual.

    Args:
        problem: The Coulomb problem.
        P: Impulses in [N s], shape (r,).
        u: Their velocities ``D P + b`` in [m/s], shape (r,).
        residual: Their natural-map residual in [m/s].
        target: Natural-map residual in [m/s] at which to stop.

    Returns:
        None where D is not banded (:func:`band_order`); else the best impulses (r,), their
        velocities (r,), natural-map residual in [m/s], and whether a solve improved on
        ``P``.
    """
    band = band_order(problem)
    if band is None:
        return None
    best, improved, previous = (P, u, residual), False, None
    for _ in range(STATUS_SOLVES):
        statuses = contact_statuses(problem, best[0], best[1])
        if previous is not None and all(map(np.array_equal, statuses, previous)):
            break  # the same equations: the same impulses
        candidate = solve_on_statuses(problem, band, *statuses)
        trial = None if candidate is None else _scored(problem, candidate)
        if trial is None or not trial[2] < best[2]:  # kept only where the residual drops
            break
        best, improved, previous = trial, True, statuses
        if best[2] <= target:
            break
    return best[0], best[1], best[2], improved


def _scored(problem: CoulombProblem, P: Vector) -> tuple[Vector, Vector, float]:
    """Impulses P (r,), their velocities (r,) and natural-map residual in [m/s]."""
    u = problem.velocity(P)
    return P, u, problem.residual(P, u)


@functools.lru_cache(maxsize=ORDERS)
def _band_order(tangents: bytes, equalities: int, pattern: bytes) -> BandOrder | None:
    """The reverse Cuthill–McKee order of the contacts' coupling graph, if D is banded in it.

    Args:
        tangents: The bytes of the problem's tangent counts (an intp array).
        equalities: Its bilateral rows.
        pattern: D's non-zero pattern, row by row, packed in bits (``np.packbits``).

    Returns:
        None where the half bandwidth exceeds :data:`BANDWIDTH_FRACTION` of the rows.
    """
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    counts = np.frombuffer(tangents, dtype=np.intp)
    group = row_groups(counts, equalities)
    size, nodes = group.size, counts.size + equalities
    bits = np.unpackbits(np.frombuffer(pattern, dtype=np.uint8), count=size * size)
    nonzero = bits.reshape(size, size).astype(bool)
    member = np.zeros((size, nodes))
    member[np.arange(size), group] = 1.0
    coupled = member.T @ nonzero @ member != 0.0  # (nodes, nodes)
    node_order = reverse_cuthill_mckee(csr_matrix(coupled), symmetric_mode=True)
    rank = np.empty(nodes, dtype=np.intp)
    rank[node_order] = np.arange(nodes)
    order = np.argsort(rank[group], kind="stable").astype(np.intp)  # a node's rows together
    position = np.empty(size, dtype=np.intp)
    position[order] = np.arange(size)
    rows, columns = np.nonzero(nonzero)
    spread = np.abs(position[rows] - position[columns]).max(initial=0)
    group_span = int(np.bincount(group).max(initial=1)) - 1  # the local rows of a status
    # A sliding spatial contact's tangential row combines its two rows of D (adjacent).
    bandwidth = int(max(spread + bool(np.any(counts == 2)), group_span))
    if bandwidth > BANDWIDTH_FRACTION * size:
        return None
    # LAPACK's band storage of kl = ku = k: entry (i, j) at row 2k + i - j, column j.
    storage_row = np.arange(3 * bandwidth + 1)[:, None]
    column = np.arange(size)[None, :]
    band_row = np.broadcast_to(storage_row - 2 * bandwidth + column, (3 * bandwidth + 1, size))
    valid = (storage_row >= bandwidth) & (band_row >= 0) & (band_row < size)
    rows_at = np.where(valid, np.clip(band_row, 0, size - 1), 0)

    def flat(shift: int) -> NDArray[np.intp]:
        """Flat index into D of the entry (i + shift, j) of each storage entry (clipped)."""
        return np.asarray(order[np.clip(rows_at + shift, 0, size - 1)] * size + order[column])

    band = BandOrder(order, position, bandwidth, flat(0), flat(1), flat(-1), valid, rows_at)
    for array in band[:2] + band[3:]:
        array.flags.writeable = False  # shared by every problem of the same pattern
    return band


def contact_statuses(
    problem: CoulombProblem, P: Vector, u: Vector
) -> tuple[NDArray[np.intp], Vector, Vector]:
    r"""Status of each contact (m,) that the natural map suggests at (P, u), and directions.

    Returns:
        :data:`SEPARATE`, :data:`STICK` or :data:`SLIDE` per contact (frictionless contacts
        separate or stick: their normal row closed); the unit sliding direction d of each
        contact, shape (m, 2) (0 where it does not slide); and the turning of d with the
        sliding velocity, :math:`C = \mu P_n (I - d d^T) / \|u_t\|` in [N s per m/s],
        shape (m, 2, 2), on the spatial contacts that slide (0 elsewhere).
    """
    m, mu, sigma = problem.m, problem.mu, problem.normal_scale
    u_t = problem.tangential(u)
    speed = tangential_norms(u_t)
    z_n = sigma * P[:m] - (u[:m] + mu * speed)  # the natural map's argument, [m/s]
    z_t = sigma[:, None] * problem.tangential(P) - u_t
    z_t_norm = tangential_norms(z_t)
    status = np.full(m, SLIDE, dtype=np.intp)
    status[(problem.tangents == 0) | (z_t_norm < mu * z_n)] = STICK
    status[mu * z_t_norm <= -z_n] = SEPARATE
    sliding = status == SLIDE
    # -u_t where the contact moves; z_t (non-zero outside the cone) where it does not.
    along = np.where((speed > 0.0)[:, None], -u_t, z_t)
    norms = np.where(speed > 0.0, speed, z_t_norm)
    norms[norms == 0.0] = 1.0  # frictionless tangential rows (mu = 0): no direction
    directions = np.zeros((m, 2))
    directions[sliding] = along[sliding] / norms[sliding, None]
    turning = np.zeros((m, 2, 2))
    turns = np.flatnonzero(sliding & (problem.tangents == 2) & (speed > 0.0))
    d = directions[turns]
    gain = mu[turns] * np.maximum(P[turns], 0.0) / speed[turns]  # [N s per m/s]
    turning[turns] = gain[:, None, None] * (np.eye(2) - d[:, :, None] * d[:, None, :])
    return status, directions, turning


@functools.cache
def _gbsv() -> Any:
    """LAPACK's ``dgbsv`` (band LU with partial pivoting, then the solve)."""
    from ucontrol.solvers.lapack_routines import lapack_routine

    return lapack_routine("dgbsv")


def solve_on_statuses(
    problem: CoulombProblem,
    band: BandOrder,
    status: NDArray[np.intp],
    directions: Vector,
    turning: Vector,
) -> Vector | None:
    r"""Impulses (r,) satisfying the equations of ``status`` (module docstring) by band LU.

    A spatial contact's sliding direction depends on its velocity: its tangential rows are
    Newton's linearization :math:`C u_t + P_t - \mu P_n d = 0` of
    :math:`P_t = \mu P_n d(u_t)` about the iterate (:math:`C u_t = 0` there, ``turning``
    C), whose solves then converge quadratically where the statuses are right.

    Args:
        problem: The Coulomb problem.
        band: The band order of its D (:func:`band_order`).
        status: Status of each contact, shape (m,).
        directions: Unit sliding direction of each contact, shape (m, 2).
        turning: C of each contact, shape (m, 2, 2) (:func:`contact_statuses`).

    Returns:
        The impulses in [N s], or None where the system is singular to
        :data:`~ucontrol.solvers.alart_curnier.LSTSQ_CONDITION` or a normal impulse is
        negative.
    """
    m, size, k = problem.m, problem.size, band.bandwidth
    # Rows that keep their row of D: closed normal rows, sticking tangential rows, bilateral.
    keep = np.ones(size + 1, dtype=bool)  # last entry: sink of the missing tangent rows
    separate = np.flatnonzero(status == SEPARATE)
    keep[separate] = False
    keep[problem.tangent_rows[separate]] = False
    slide = np.flatnonzero(status == SLIDE)
    tangent_rows = problem.tangent_rows[slide]
    keep[tangent_rows] = False
    keep = keep[:size]
    own = keep[band.order].astype(float)  # per position: the factor of its own row of D
    rhs = np.where(keep, -problem.b, 0.0)[band.order]
    D, rows_at = problem.D.ravel(), band.band_row
    turns = np.flatnonzero(turning[:, 0, 0] + turning[:, 1, 1] > 0.0)
    if turns.size:  # C (D_t P + b_t) on a turning contact's two tangential rows
        first, second = band.position[problem.tangent_rows[turns].T]  # adjacent positions
        C = turning[turns]
        own[first], own[second] = C[:, 0, 0], C[:, 1, 1]
        next_row, previous_row = np.zeros(size), np.zeros(size)
        next_row[first], previous_row[second] = C[:, 0, 1], C[:, 1, 0]
        b_t = problem.b[problem.tangent_rows[turns]]  # (t, 2)
        rhs[first], rhs[second] = -np.einsum("tij,tj->ti", C, b_t).T
        ab = (
            D[band.flat] * own[rows_at]
            + D[band.flat_next] * next_row[rows_at]
            + D[band.flat_previous] * previous_row[rows_at]
        ) * band.valid
    else:
        ab = D[band.flat] * (own[rows_at] * band.valid)
    local = band.position[~keep]  # separating rows and sliding tangential rows: P_i ...
    ab[2 * k, local] += 1.0
    for component in range(2):  # ... - mu d P_n on the sliding tangential rows
        present = tangent_rows[:, component] < size
        row = band.position[tangent_rows[present, component]]
        normal = band.position[slide[present]]
        ab[2 * k + row - normal, normal] -= (
            problem.mu[slide[present]] * directions[slide[present], component]
        )
    lu, _, x, info = _gbsv()(k, k, ab, rhs[:, None], overwrite_ab=1)
    pivots = np.abs(lu[2 * k])
    if info != 0 or not pivots.min(initial=np.inf) > LSTSQ_CONDITION * pivots.max(initial=0.0):
        return None
    P = np.empty(size)
    P[band.order] = x[:, 0]
    if np.any(P[:m] < -1e-12 * (1.0 + np.abs(P[:m]).max(initial=0.0))):
        return None
    P[:m] = np.maximum(P[:m], 0.0)
    return P
