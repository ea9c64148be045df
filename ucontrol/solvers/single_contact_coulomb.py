r"""One contact with Coulomb friction, solved by enumerating its statuses on Python floats.

A problem of one contact (:math:`r \le 3` rows, no bilateral row) is small enough that numpy's
fixed cost per call is most of a vectorized solve. Its three statuses are tried in turn, each an
explicit computation (Acary & Brogliato 2008, §13.3 enumerate them the same way):

1. **separate**: :math:`P = 0`, valid when :math:`b_n \ge 0`;
2. **stick**: :math:`D P = -b` (Cramer's rule), valid when :math:`P_n \ge 0` and
   :math:`\|P_t\| \le \mu P_n`;
3. **slide**: :math:`P = P_n (1, \mu d)` with :math:`u_n = 0`, which gives
   :math:`P_n = -b_n / (D_{nn} + \mu D_{nt} d)`, and :math:`d` opposite to the slip
   :math:`u_t = b_t + P_n (D_{tn} + \mu D_{tt} d)`. A planar contact tries :math:`d = \pm 1`; a
   spatial one writes :math:`d = (\cos\theta, \sin\theta)` and solves
   :math:`g(\theta) = u_t \times d = 0` (with :math:`u_t \cdot d < 0`) by the secant method,
   started from the direction opposite to the slip of the frictionless impulse.

The first valid status is returned (with large friction a contact can have several solutions,
Painlevé's paradox; sticking is preferred, as the Tresca fixed point does). ``None`` says none was
found (a singular D, a secant that did not converge): the caller then solves the problem by its
general method.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ucontrol.solvers.coulomb_problem import CoulombProblem

Vector = NDArray[np.float64]

#: Secant iterations of the sliding direction of a spatial contact.
SECANT_ITERATIONS = 40
#: Size of the cross product u_t × d, relative to the slip, at which the secant stops.
SECANT_TOLERANCE = 1e-15
#: Arcs of the scan for the sliding direction where the secant fails.
SCAN_POINTS = 16


def solve_single_contact(problem: CoulombProblem) -> Vector | None:
    """Impulses (r,) solving a one-contact problem, or None (see the module docstring).

    Args:
        problem: A Coulomb problem with ``m == 1`` and no bilateral row.
    """
    b = problem.b.tolist()
    if b[0] >= 0.0:
        return np.zeros(problem.size)
    D = problem.D.tolist()
    mu = float(problem.mu[0])
    tangents = int(problem.tangents[0])
    if tangents == 0 or mu == 0.0:
        if D[0][0] <= 0.0:
            return None
        P = np.zeros(problem.size)
        P[0] = -b[0] / D[0][0]
        return P
    stick = _solve_stick(D, b)
    if stick is not None and stick[0] >= 0.0:
        if math.hypot(*stick[1:]) <= mu * stick[0]:
            return np.array(stick)
    slide = _slide_planar(D, b, mu) if tangents == 1 else _slide_spatial(D, b, mu)
    return None if slide is None else np.array(slide)


def _solve_stick(D: list[list[float]], b: list[float]) -> list[float] | None:
    """``-D⁻¹ b`` for D of size 2 or 3 (Cramer's rule), or None where D is singular."""
    if len(b) == 2:
        (a, c), (e, f) = D
        det = a * f - c * e
        if not abs(det) > 1e-14 * (abs(a * f) + abs(c * e)):
            return None
        return [-(f * b[0] - c * b[1]) / det, -(a * b[1] - e * b[0]) / det]
    (a, c, e), (f, g, h), (i, j, k) = D
    minors = (g * k - h * j, h * i - f * k, f * j - g * i)
    det = a * minors[0] + c * minors[1] + e * minors[2]
    scale = abs(a * minors[0]) + abs(c * minors[1]) + abs(e * minors[2])
    if not abs(det) > 1e-14 * scale:
        return None
    # Inverse by the adjugate: rows of D⁻¹ times -b.
    inverse = (
        (minors[0], e * j - c * k, c * h - e * g),
        (minors[1], a * k - e * i, e * f - a * h),
        (minors[2], c * i - a * j, a * g - c * f),
    )
    return [-(row[0] * b[0] + row[1] * b[1] + row[2] * b[2]) / det for row in inverse]


def _slide_planar(D: list[list[float]], b: list[float], mu: float) -> list[float] | None:
    """Sliding impulses of a planar contact, d opposite to the frictionless slip tried first."""
    free = b[1] - b[0] / D[0][0] * D[1][0]  # slip under the frictionless impulse [m/s]
    first = -1.0 if free > 0.0 else 1.0
    for sign in (first, -first):
        a = D[0][0] + mu * sign * D[0][1]  # u_n per P_n [m/s per N s]
        if a <= 0.0:
            continue
        P_n = -b[0] / a
        u_t = b[1] + P_n * (D[1][0] + mu * sign * D[1][1])
        if u_t * sign <= 0.0:
            return [P_n, mu * sign * P_n]
    return None


def _slide_spatial(D: list[list[float]], b: list[float], mu: float) -> list[float] | None:
    """Sliding impulses of a spatial contact: a root of u_t × d in the slip's direction θ.

    The secant method from the direction opposite to the frictionless slip first; where it
    does not converge to a valid root, the circle is scanned in :data:`SCAN_POINTS` arcs and
    each sign change of the cross product refined by the Illinois method.
    """

    def slip(theta: float) -> tuple[float, float, float, float] | None:
        c, s = math.cos(theta), math.sin(theta)
        a = D[0][0] + mu * (D[0][1] * c + D[0][2] * s)
        if a <= 0.0:
            return None
        P_n = -b[0] / a
        u_1 = b[1] + P_n * (D[1][0] + mu * (D[1][1] * c + D[1][2] * s))
        u_2 = b[2] + P_n * (D[2][0] + mu * (D[2][1] * c + D[2][2] * s))
        return P_n, u_1, u_2, u_1 * s - u_2 * c  # u_t × d

    def accept(theta: float, value: tuple[float, float, float, float]) -> list[float] | None:
        P_n, u_1, u_2, _ = value
        c, s = math.cos(theta), math.sin(theta)
        if P_n < 0.0 or u_1 * c + u_2 * s > 0.0:
            return None
        return [P_n, mu * P_n * c, mu * P_n * s]

    free = -b[0] / D[0][0]  # frictionless normal impulse
    theta = math.atan2(-(b[2] + free * D[2][0]), -(b[1] + free * D[1][0]))
    current = slip(theta)
    if current is None:
        return None
    tolerance = SECANT_TOLERANCE * (abs(current[1]) + abs(current[2]) + abs(b[0]) + 1e-300)
    previous_theta, previous_g = theta, current[3]
    theta = math.atan2(-current[2], -current[1])  # one fixed-point step
    for _ in range(SECANT_ITERATIONS):
        current = slip(theta)
        if current is None or current[3] == previous_g:
            break
        if abs(current[3]) <= tolerance:
            found = accept(theta, current)
            if found is not None:
                return found
            break
        g = current[3]
        theta, previous_theta = theta - g * (theta - previous_theta) / (g - previous_g), theta
        previous_g = g
    arcs = [2.0 * math.pi * k / SCAN_POINTS for k in range(SCAN_POINTS + 1)]
    values = [slip(angle) for angle in arcs]
    for k in range(SCAN_POINTS):
        left, right = values[k], values[k + 1]
        if left is None or right is None or (left[3] > 0.0) == (right[3] > 0.0):
            continue
        root = _illinois(slip, arcs[k], arcs[k + 1], left[3], right[3], tolerance)
        if root is not None:
            found = accept(*root)
            if found is not None:
                return found
    return None


def _illinois(
    function: Any, low: float, high: float, f_low: float, f_high: float, tolerance: float
) -> tuple[float, tuple[float, float, float, float]] | None:
    """A root of ``function(θ)[3]`` in [low, high], where it changes sign (Illinois method)."""
    side = 0
    for _ in range(SECANT_ITERATIONS):
        theta = (low * f_high - high * f_low) / (f_high - f_low)
        value = function(theta)
        if value is None:
            return None
        if abs(value[3]) <= tolerance or high - low <= 1e-15:
            return theta, value
        if (value[3] > 0.0) == (f_high > 0.0):
            high, f_high = theta, value[3]
            if side == -1:
                f_low *= 0.5
            side = -1
        else:
            low, f_low = theta, value[3]
            if side == 1:
                f_high *= 0.5
            side = 1
    return None
