r"""The velocity-level Coulomb contact problem of one Moreau–Jean step, and its residual.

m contacts; contact a has a normal row and :math:`k_a \in \{0, 1, 2\}` tangential rows (0:
frictionless or a joint stop, 1: planar friction, 2: spatial friction). The rows are stacked
**normals first** (rows 0 … m-1), then the tangential rows contact after contact. With
:math:`u = D P + b` (:math:`D = H W^{-1} H^T`, :math:`b = H v_\text{free}` plus the restitution
term :math:`e_a u_{n,a}^-` on the normal rows), each contact obeys Coulomb's law at velocity
level with Newton's restitution, in De Saxcé's form

.. math:: K_a \ni P_a \perp \hat u_a \in K_a^*, \qquad
          \hat u_a = u_a + \mu_a \|u_{t,a}\| e_n, \qquad
          K_a = \{ \|P_t\| \le \mu_a P_n \},

the second-order cone complementarity problem of Acary & Brogliato (2008) ch. 13: a separating
contact has :math:`P_a = 0, u_n \ge 0`; a sticking one :math:`u_a = 0, \|P_t\| \le \mu P_n`; a
sliding one :math:`u_n = 0, P_t = -\mu P_n u_t / \|u_t\|`.

Its **natural-map residual** (:meth:`CoulombProblem.residual`), in [m/s], is

.. math:: r = \max_a \big\| \sigma_a P_a - \Pi_{K_a}(\sigma_a P_a - \hat u_a) \big\|_\infty,

with :math:`\sigma_a = D_{n_a n_a}` turning impulses into velocities; it vanishes exactly at
solutions of the true (non-convex) Coulomb problem, and for frictionless contacts it is the
LCP's :math:`|\min(\sigma P, u)|` of :func:`~ucontrol.solvers.complementarity_residual`.
Up to :data:`~ucontrol.solvers.contact_solution.PYTHON_RESIDUAL_SIZE` rows it is computed
by a loop on Python floats, whose cost is a fraction of the numpy expression's fixed costs per
call on so few rows (a Panda's one contact: docs/benchmarks.md). Both, and the compiled Newton
step of :mod:`~ucontrol.solvers.compiled_coulomb_newton`, evaluate one definition of a
contact's terms, :func:`natural_map_errors` (with :func:`project_on_cone`), written once over
the operations of each kind of number (:class:`ConeOps`: :data:`FLOAT_OPS`,
:data:`NUMPY_OPS`, casadi's).

**Bilateral rows.** A closed chain adds ``equalities`` rows :math:`J_b` **last** (after the
tangential rows), whose impulses :math:`P_b` are free in sign and whose velocities vanish,
:math:`u_b = D_{b\cdot} P + b_b = 0`: the mixed Coulomb problem of a Moreau–Jean step with
bilateral constraints. Their residual is :math:`\|u_b\|_\infty`, and the problem's residual
the larger of it and the contacts' natural-map residual.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from ucontrol.exceptions import InvalidParameterError, ShapeError
from ucontrol.solvers.contact_solution import PYTHON_RESIDUAL_SIZE

Vector = NDArray[np.float64]

#: Row layouts (tangent counts and bilateral rows) kept derived, least recently used dropped.
LAYOUTS = 64


class CoulombProblem:
    """Data of a Coulomb contact problem (see the module docstring for the row layout).

    Args:
        D: Delassus matrix, symmetric positive semidefinite, shape (r, r), [m/s per N s].
        b: Free velocity plus restitution, shape (r,), in [m/s].
        mu: Friction coefficient of each contact, >= 0, shape (m,).
        tangents: Tangential rows of each contact (0, 1 or 2), shape (m,); the contacts
            with 0 are frictionless whatever their ``mu``.
        equalities: Number of bilateral rows, last in ``D`` and ``b`` (module docstring).

    Attributes:
        m: Number of contacts.
        equalities: Number of bilateral rows, the last ones.
        equality_rows: Indices of the bilateral rows, shape (equalities,).
        size: Number of rows r = m + sum(tangents) + equalities.
        tangent_rows: Row of the first and second tangential component of each contact,
            shape (m, 2); ``size`` where the contact has no such row (gathers read a 0 there).
        row_groups: The group of each row, shape (r,): its contact's index, or m + j for
            bilateral row j (:func:`row_groups`).
        spatial: Whether any contact has two tangential rows.

    Raises:
        ShapeError: The shapes do not fit together.
        InvalidParameterError: A friction coefficient is negative, a tangent count is not
            0, 1 or 2, or ``equalities`` is negative.
    """

    def __init__(
        self,
        D: Vector,
        b: Vector,
        mu: Vector,
        tangents: NDArray[np.intp],
        equalities: int = 0,
    ) -> None:
        tangents = np.asarray(tangents, dtype=np.intp)
        mu = np.asarray(mu, dtype=float)
        if int(equalities) != equalities or equalities < 0:
            raise InvalidParameterError("equalities", equalities, "an integer >= 0")
        layout = _layout(tangents.tobytes(), int(equalities))
        m, size = layout.m, layout.size
        if b.shape != (size,):
            raise ShapeError("b", (size,), b.shape)
        if D.shape != (size, size):
            raise ShapeError("D", (size, size), D.shape)
        if mu.shape != (m,):
            raise ShapeError("mu", (m,), mu.shape)
        mu_values = mu.tolist()
        if any(value < 0.0 for value in mu_values):
            raise InvalidParameterError("mu", mu_values, ">= 0 for every contact")
        self.D = D
        self.b = b
        self.tangents = layout.tangents
        self.mu = mu.copy() if layout.all_frictional else np.where(layout.frictional, mu, 0.0)
        self.m = m
        self.equalities = layout.equalities
        self.size = size
        self.tangent_rows = layout.tangent_rows
        self.spatial = layout.spatial
        self.equality_rows = layout.equality_rows
        self.row_groups = layout.row_groups
        self._layout = layout

    @functools.cached_property
    def normal_scale(self) -> Vector:
        """Diagonal of D on the normal rows (1 where it vanishes), [m/s per N s], shape (m,)."""
        scale = self.D.diagonal()[: self.m].copy()
        scale[scale <= 0.0] = 1.0
        return scale

    @functools.cached_property
    def _padded(self) -> Vector:
        """Rows (r,) and a last entry that stays 0: gathers of missing tangent rows read it."""
        return np.zeros(self.size + 1)

    def velocity(self, P: Vector) -> Vector:
        """Constraint velocities with restitution ``D P + b`` in [m/s], shape (r,)."""
        return self.D @ P + self.b

    def tangential(self, x: Vector) -> Vector:
        """The tangential components of stacked rows ``x`` (r,), per contact, shape (m, 2).

        Missing components (frictionless or planar contacts) are 0.
        """
        padded = self._padded  # its last entry stays 0
        padded[: self.size] = x
        return padded[self.tangent_rows]

    def within_cones(self, P: Vector) -> Vector:
        r"""``P`` (r,) with each tangential impulse beyond :math:`\mu P_n` scaled onto it.

        A solution accepted at the residual tolerance can leave a cone by that tolerance; the
        scaling keeps the normal impulses and the sliding directions, so that Coulomb's
        inequality :math:`\lVert P_t \rVert \le \mu P_n` holds to rounding. ``P`` itself is
        returned where every contact is inside its cone.
        """
        m = self.m
        if m == 0:
            return P
        norms = tangential_norms(self.tangential(P))
        bounds = self.mu * np.maximum(P[:m], 0.0)
        over = np.flatnonzero(norms > bounds)
        if over.size == 0:
            return P
        inside = np.append(P, 0.0)  # the last entry: sink of the missing tangent rows
        rows = self.tangent_rows[over]
        inside[rows] *= (bounds[over] / norms[over])[:, None]
        return inside[: self.size]

    def residual(self, P: Vector, velocity: Vector | None = None) -> float:
        """Natural-map residual of the Coulomb problem at impulses ``P`` (r,), in [m/s].

        Args:
            P: Stacked impulses in [N s], shape (r,).
            velocity: ``D P + b`` if already computed, shape (r,).
        """
        u = self.velocity(P) if velocity is None else velocity
        if self.size <= PYTHON_RESIDUAL_SIZE:
            return self._residual_on_floats(P.tolist(), u.tolist())
        bilateral = (
            float(np.max(np.abs(u[self.size - self.equalities :]))) if self.equalities else 0.0
        )
        if self.m == 0:
            return bilateral
        m, padded, sigma = self.m, self._padded, self.normal_scale  # padded[-1] stays 0
        padded[: self.size] = u
        u_t = padded[self.tangent_rows]
        padded[: self.size] = P
        P_t = padded[self.tangent_rows]
        errors = natural_map_errors(
            NUMPY_OPS, sigma, (P[:m], P_t[:, 0], P_t[:, 1]), (u[:m], u_t[:, 0], u_t[:, 1]), self.mu
        )
        return float(max(*(error.max() for error in errors), bilateral))

    def _residual_on_floats(self, P: list[float], u: list[float]) -> float:
        """:meth:`residual` by a loop on Python floats (problems of a few rows, module docstring).

        Contact by contact, the terms of the numpy form (:func:`natural_map_errors` on
        :data:`FLOAT_OPS`); a NaN anywhere gives NaN.
        """
        m, size = self.m, self.size
        residual = check = 0.0  # check: the sum of every term, NaN if any of them is
        for value in u[size - self.equalities :]:
            residual = max(residual, abs(value))
            check += value
        if m:
            P.append(0.0)  # entry `size`: the missing tangent rows read 0
            u.append(0.0)
            D, mu = self.D, self.mu.tolist()
            for a, (i, j) in enumerate(self._layout.row_pairs):
                sigma = D.item(a, a)
                sigma = 1.0 if sigma <= 0.0 else sigma
                errors = natural_map_errors(
                    FLOAT_OPS, sigma, (P[a], P[i], P[j]), (u[a], u[i], u[j]), mu[a]
                )
                for error in errors:
                    residual = max(residual, error)
                    check += error
        return math.nan if math.isnan(check) else residual


class _Layout(NamedTuple):
    """What a :class:`CoulombProblem` derives from its tangent counts alone (read-only arrays)."""

    tangents: NDArray[np.intp]
    m: int
    equalities: int
    size: int
    tangent_rows: NDArray[np.intp]
    spatial: bool
    equality_rows: NDArray[np.intp]
    frictional: NDArray[np.bool_]
    all_frictional: bool
    row_pairs: tuple[tuple[int, int], ...]
    row_groups: NDArray[np.intp]


@functools.lru_cache(maxsize=LAYOUTS)
def _layout(tangents: bytes, equalities: int) -> _Layout:
    """The row layout of ``tangents`` (the bytes of an intp array) and ``equalities``.

    Derived once per layout: the successive problems of a time-stepping run share a few.

    Raises:
        InvalidParameterError: A tangent count is not 0, 1 or 2.
    """
    counts = np.frombuffer(tangents, dtype=np.intp)
    if np.any((counts < 0) | (counts > 2)):
        raise InvalidParameterError("tangents", counts.tolist(), "0, 1 or 2 per contact")
    m = counts.size
    size = m + int(counts.sum()) + equalities
    first = m + np.concatenate(([0], np.cumsum(counts)[:-1])).astype(np.intp)
    tangent_rows = np.column_stack(
        (np.where(counts > 0, first, size), np.where(counts > 1, first + 1, size))
    )
    equality_rows = np.arange(size - equalities, size)
    frictional = counts > 0
    groups = row_groups(counts, equalities)
    for array in (tangent_rows, equality_rows, frictional, groups):
        array.flags.writeable = False
    return _Layout(
        counts,
        m,
        equalities,
        size,
        tangent_rows,
        bool(np.any(counts == 2)),
        equality_rows,
        frictional,
        bool(frictional.all()),
        tuple((int(i), int(j)) for i, j in tangent_rows.tolist()),
        groups,
    )


def row_groups(tangents: NDArray[np.intp], equalities: int) -> NDArray[np.intp]:
    """The group of each row (r,): its contact's index, or m + j for bilateral row j.

    Args:
        tangents: Tangential rows of each contact (0, 1 or 2), shape (m,).
        equalities: Number of bilateral rows, the last ones.
    """
    m = tangents.size
    return np.concatenate(
        (np.arange(m), np.repeat(np.arange(m), tangents), m + np.arange(equalities))
    ).astype(np.intp)


def tangential_norms(x_t: Vector) -> Vector:
    """Euclidean norm of each row of ``x_t`` (m, 2), shape (m,): one ufunc call (``hypot``)."""
    return np.hypot(x_t[:, 0], x_t[:, 1])


class ConeOps(NamedTuple):
    """The operations the cone's expressions use, on one kind of number.

    The definitions written once over these (:func:`project_on_cone`,
    :func:`natural_map_errors`, :func:`~ucontrol.solvers.alart_curnier.alart_curnier_terms`)
    are evaluated on Python floats (:data:`FLOAT_OPS`, problems of a few rows), numpy arrays
    of contacts (:data:`NUMPY_OPS`) and casadi expressions (the compiled Newton step,
    :mod:`~ucontrol.solvers.compiled_coulomb_newton`).

    Attributes:
        hypot: Euclidean norm of two components.
        fmax: Elementwise larger of two values.
        fmin: Elementwise smaller of two values.
        sqrt: Square root.
        fabs: Absolute value.
        logical_and: Elementwise and of two conditions.
        where: ``where(condition, x, y)``.
        ratio: ``ratio(x, y, skip)``: x / y where y > 0 and not ``skip``, else 0 (never a
            division by 0, nor an overflow where ``skip`` holds).
    """

    hypot: Callable[[Any, Any], Any]
    fmax: Callable[[Any, Any], Any]
    fmin: Callable[[Any, Any], Any]
    sqrt: Callable[[Any], Any]
    fabs: Callable[[Any], Any]
    logical_and: Callable[[Any, Any], Any]
    where: Callable[[Any, Any, Any], Any]
    ratio: Callable[[Any, Any, Any], Any]


def _float_ratio(x: float, y: float, skip: bool) -> float:
    """:attr:`ConeOps.ratio` on Python floats."""
    return x / y if y > 0.0 and not skip else 0.0


def _array_ratio(x: Vector, y: Vector, skip: NDArray[np.bool_]) -> Vector:
    """:attr:`ConeOps.ratio` on numpy arrays."""
    return np.divide(x, y, out=np.zeros_like(y), where=(y > 0.0) & ~skip)


#: The cone's operations on Python floats.
FLOAT_OPS = ConeOps(
    math.hypot,
    max,
    min,
    math.sqrt,
    abs,
    lambda a, b: a and b,
    lambda c, x, y: x if c else y,
    _float_ratio,
)
#: The cone's operations on numpy arrays (one entry per contact).
NUMPY_OPS = ConeOps(
    np.hypot, np.maximum, np.minimum, np.sqrt, np.abs, np.logical_and, np.where, _array_ratio
)


def project_on_cone(ops: ConeOps, z_n: Any, z_1: Any, z_2: Any, mu: Any) -> tuple[Any, Any, Any]:
    r"""Euclidean projection of :math:`(z_n, z_1, z_2)` on :math:`\{\|x_t\| \le \mu x_n\}`.

    Args:
        ops: The operations of the numbers given (:class:`ConeOps`).
        z_n: Normal component(s).
        z_1: First tangential component(s).
        z_2: Second tangential component(s) (0 for a planar contact).
        mu: Cone aperture(s) (friction coefficients) >= 0.

    Returns:
        The projected normal and two tangential components.
    """
    t = ops.hypot(z_1, z_2)
    inside = ops.logical_and(t <= mu * z_n, z_n >= 0.0)  # z_n >= 0 matters for mu = 0
    # On the polar cone (mu t <= -z_n) the boundary's normal component is <= 0: clipped to
    # the apex, 0.
    boundary_n = ops.fmax((z_n + mu * t) / (1.0 + mu * mu), 0.0)
    # Outside the cone the ratio is below 1; inside it is not used, and with a subnormal t
    # (impulses decaying down a long column of beads) it would overflow.
    ratio = ops.where(inside, 1.0, ops.ratio(mu * boundary_n, t, inside))
    return ops.where(inside, z_n, boundary_n), ratio * z_1, ratio * z_2


def natural_map_errors(
    ops: ConeOps, sigma: Any, P: tuple[Any, Any, Any], u: tuple[Any, Any, Any], mu: Any
) -> tuple[Any, Any, Any]:
    r"""The natural map's terms :math:`|\sigma P - \Pi_K(\sigma P - \hat u)|` of a contact.

    Its normal and two tangential components, in [m/s] (module docstring); the residual is
    their largest over the contacts.

    Args:
        ops: The operations of the numbers given (:class:`ConeOps`).
        sigma: :math:`\sigma_a` in [m/s per N s].
        P: Normal and two tangential impulses in [N s] (0 for a missing tangential row).
        u: Normal and two tangential velocities in [m/s] (0 for a missing tangential row).
        mu: Friction coefficient(s) >= 0.
    """
    sigma_P = (sigma * P[0], sigma * P[1], sigma * P[2])
    z_n = sigma_P[0] - (u[0] + mu * ops.hypot(u[1], u[2]))
    pi = project_on_cone(ops, z_n, sigma_P[1] - u[1], sigma_P[2] - u[2], mu)
    return (
        ops.fabs(sigma_P[0] - pi[0]),
        ops.fabs(sigma_P[1] - pi[1]),
        ops.fabs(sigma_P[2] - pi[2]),
    )
