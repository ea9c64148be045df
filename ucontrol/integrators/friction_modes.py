r"""Contact modes with planar Coulomb friction by enumeration: the acceleration or impulse problem.

Constraints at contact with normal rows :math:`J_n` (m) and, for the frictional ones, one
tangential row each :math:`J_t` (k, one tangent: planar friction) see the linear map

.. math::

    \begin{pmatrix} y_n \\ y_t \end{pmatrix}
    = W \begin{pmatrix} \lambda_n \\ \lambda_t \end{pmatrix} + b, \qquad
    W = \begin{pmatrix} J_n \\ J_t \end{pmatrix} M^{-1}
        \begin{pmatrix} J_n^T & J_t^T \end{pmatrix},

y being the normal and tangential accelerations (b their values without contact forces,
:math:`J a_\text{free} + \dot J v`) or, at an impact, :math:`u_n^+ + e\,u_n^-` and
:math:`u_t^+` (b then :math:`(1 + e) u_n^-` and :math:`u_t^-`, λ the impulses). Each
constraint takes one normal mode, closed (:math:`y_n = 0`, :math:`\lambda_n \ge 0`) or open
(:math:`\lambda_n = 0`, :math:`y_n \ge 0`), and each closed frictional one a tangential mode:
stick (:math:`y_t = 0`, :math:`|\lambda_t| \le \mu \lambda_n`) or slip in the direction
:math:`s = \pm 1` (:math:`\lambda_t = -\mu s \lambda_n`, :math:`s\,y_t \ge 0`). A mode is a
linear system; :func:`friction_modes` enumerates them (closed before open, stick before slip)
and returns the first consistent one: Brogliato's Coulomb complementarity problem solved
exactly (*Nonsmooth Mechanics*, §5.4: with friction its solution may be missing or not
unique, Painlevé's paradoxes; none consistent is a :class:`PainleveError`).

The enumeration costs :math:`2^m 3^k` solves of size at most m + k: meant for the few contacts
of a planar mechanism (a journal in its bearing, a foot, a sliding block), capped by
``MAX_MODES``.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ucontrol.exceptions import PainleveError

Vector = NDArray[np.float64]

#: Largest number of mode combinations enumerated (2^m 3^k).
MAX_MODES = 20_000
#: The three tangential modes, in the order tried: stick, slip +, slip -.
STICK, SLIP_POSITIVE, SLIP_NEGATIVE = 0, 1, 2
_SIGNS = (0.0, 1.0, -1.0)
#: Singular values of a mode's system below this times the largest are dropped.
_RCOND = 1e-12
#: Relative residual above which a mode's equalities have no solution (a singular system).
_RESIDUAL = 1e-9


@dataclass(frozen=True)
class FrictionModes:
    """The consistent mode found and its forces (or impulses).

    Attributes:
        closed: Normal mode of each constraint, shape (m,).
        stick: Tangential rows in stick, shape (k,) (False for those of open constraints).
        sign: Slip direction s of each tangential row, ±1, 0 in stick or open, shape (k,).
        lambda_n: Normal forces in [N] (impulses in [N s]), shape (m,).
        lambda_t: Tangential ones, shape (k,).
    """

    closed: NDArray[np.bool_]
    stick: NDArray[np.bool_]
    sign: Vector
    lambda_n: Vector
    lambda_t: Vector


def friction_modes(
    W: Vector,
    b: Vector,
    friction: Vector,
    owner: NDArray[np.intp],
    allowed: NDArray[np.bool_],
    sliding: NDArray[np.bool_],
    *,
    value_tolerance: float,
    force_tolerance: float = 1e-12,
) -> FrictionModes:
    r"""The first consistent contact mode (module docstring).

    Args:
        W: The map from (λ_n, λ_t) to (y_n, y_t), shape (m + k, m + k).
        b: y at zero force, shape (m + k,).
        friction: μ of each tangential row, shape (k,).
        owner: The normal row (0..m-1) of each tangential row, shape (k,).
        allowed: Tangential modes allowed per row (stick, slip +, slip -), shape (k, 3): a
            sliding contact keeps its direction, one that just left stick cannot stick.
        sliding: Tangential rows already sliding (:math:`u_t \ne 0`, acceleration level):
            their slip direction is that of the velocity, :math:`s y_t \ge 0` not asked;
            shape (k,).
        value_tolerance: Largest violation of :math:`y_n \ge 0` (open) or :math:`s y_t \ge 0`
            (slip) accepted, in the units of y.
        force_tolerance: Largest violation of :math:`\lambda_n \ge 0` or of the cone
            accepted, relative to the largest force of the mode (absolute below 1).

    Raises:
        PainleveError: No mode is consistent, or more than ``MAX_MODES`` combinations.
    """
    problem = _Problem(W, b, friction, owner)
    k, m = friction.size, problem.m
    counts = 2**m * int(np.prod(allowed.sum(axis=1))) if k else 2**m
    if counts > MAX_MODES:
        raise PainleveError(
            "event_driven",
            float("nan"),
            f"{counts} contact modes to enumerate ({m} contacts, {k} with friction), more than "
            f"{MAX_MODES}: sustained friction by mode enumeration is for a few contacts",
        )
    choices = [np.flatnonzero(row) for row in allowed]
    for closed_tuple in itertools.product((True, False), repeat=m):
        closed = np.array(closed_tuple, dtype=bool)
        live = closed[owner] if k else np.zeros(0, dtype=bool)
        per_row = [row if live[r] else np.array([STICK]) for r, row in enumerate(choices)]
        for modes_tuple in itertools.product(*per_row):
            found = _solve_mode(problem, closed, live, np.array(modes_tuple, dtype=np.intp))
            if found is not None and _consistent(
                problem, found, ~sliding, value_tolerance, force_tolerance
            ):
                return found
    raise PainleveError(
        "event_driven",
        float("nan"),
        f"no contact mode is consistent ({m} contacts, {k} with friction, μ = "
        f"{friction.tolist()}): Painlevé's inconsistency, the rigid model with Coulomb friction "
        "has no solution here (use moreau_jean, whose impulses resolve it)",
    )


@dataclass(frozen=True)
class _Problem:
    """The map W (m + k, m + k), its offset b, μ (k,) and each tangential row's normal row."""

    W: Vector
    b: Vector
    friction: Vector
    owner: NDArray[np.intp]

    @property
    def m(self) -> int:
        """Number of normal rows."""
        return self.b.size - self.friction.size


def _solve_mode(
    problem: _Problem,
    closed: NDArray[np.bool_],
    live: NDArray[np.bool_],
    modes: NDArray[np.intp],
) -> FrictionModes | None:
    """The forces of one mode (least norm), or None when its equalities have no solution.

    ``closed`` (m,) the normal modes, ``live`` (k,) the tangential rows of closed constraints,
    ``modes`` (k,) their tangential modes.
    """
    W, b, friction, owner = problem.W, problem.b, problem.friction, problem.owner
    k, m = friction.size, problem.m
    stick = live & (modes == STICK)
    sign = np.where(live, np.take(_SIGNS, modes), 0.0)
    normals = np.flatnonzero(closed)
    sticks = np.flatnonzero(stick)
    # λ = S x, x = (λ_n of the closed, λ_t of the sticking)
    S = np.zeros((m + k, normals.size + sticks.size))
    S[normals, np.arange(normals.size)] = 1.0
    for r in np.flatnonzero(live & ~stick):
        S[m + r, int(np.searchsorted(normals, owner[r]))] = -friction[r] * sign[r]
    S[m + sticks, normals.size + np.arange(sticks.size)] = 1.0
    rows = np.concatenate((normals, m + sticks))
    A = W[rows] @ S
    x: Vector = np.zeros(0)
    if rows.size:  # least squares: redundant rows (two corners sticking) are allowed
        x = np.asarray(np.linalg.lstsq(A, -b[rows], rcond=_RCOND)[0], dtype=np.float64)
        residual = A @ x + b[rows]
        if np.max(np.abs(residual)) > _RESIDUAL * max(1.0, float(np.max(np.abs(b[rows])))):
            return None
    forces = S @ x
    return FrictionModes(closed, stick, sign, forces[:m], forces[m:])


def _consistent(
    problem: _Problem,
    found: FrictionModes,
    from_rest: NDArray[np.bool_],
    value_tolerance: float,
    force_tolerance: float,
) -> bool:
    r"""Whether a mode's forces and values satisfy its inequalities.

    The slip direction is checked (:math:`s y_t \ge 0`) on the rows ``from_rest`` (k,) only.
    """
    m, closed = problem.m, found.closed
    y = problem.W @ np.concatenate((found.lambda_n, found.lambda_t)) + problem.b
    scale = force_tolerance * max(1.0, float(np.max(np.abs(found.lambda_n), initial=0.0)))
    if np.any(found.lambda_n[closed] < -scale) or np.any(y[:m][~closed] < -value_tolerance):
        return False
    cone = problem.friction * found.lambda_n[problem.owner]
    if np.any(np.abs(found.lambda_t[found.stick]) > cone[found.stick] + scale):
        return False
    slipping = from_rest & (found.sign != 0.0)
    return not np.any(found.sign[slipping] * y[m:][slipping] < -value_tolerance)
