r"""Poincaré maps of impacting systems: periodic orbits, Floquet multipliers, bifurcations.

A periodically forced impacting system (Brogliato 2016, ch. 7) is given as an
:class:`ImpactSystem`: a smooth flow :math:`\dot x = f(t, x)` between impacts, a gap
:math:`g(t, x)` whose decreasing zero is an impact, and a reset :math:`x^+ = R(t, x^-)`. Two
Poincaré maps are built on it:

- the **stroboscopic map** :math:`x(t_0) \mapsto x(t_0 + T)` over one forcing period T;
- the **impact map** :math:`(t_k, x_k^+) \mapsto (t_{k+1}, x_{k+1}^+)` from one impact to the
  next (its section is the impact surface; the time coordinate is shifted by the orbit's
  period when a fixed point is sought).

Their Jacobians are computed two independent ways: by the variational equations
:math:`\dot\Phi = \partial_x f\,\Phi` with a **saltation matrix** at every impact,

.. math::

    S = R_x + \frac{(f^+ - R_x f^- - R_t)\, g_x}{g_x f^- + g_t},

and by central finite differences of the map. The eigenvalues of the Jacobian at a fixed point
are the orbit's Floquet multipliers (the impact map has one more, a trivial 0, from its section:
it is dropped). :func:`fixed_point` runs Newton on :math:`P^k(z) - z - \text{shift} = 0`;
:func:`continuation` follows a fixed point in one parameter and locates period doublings (a
multiplier crossing -1) and grazings (a user function of the orbit changing sign) by bisection;
:func:`orbit_diagram` iterates a map past its transient for the classical bifurcation diagram
and :func:`bifurcation_figure` draws both.

Two systems are provided with their analytic references: the ball on a sinusoidally vibrating
table (:func:`vibrating_table_ball`, :func:`vibrating_table_period_one`,
:func:`vibrating_table_flip_amplitude`) and the linear impact oscillator against a rigid stop
(:func:`impact_oscillator`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from ucontrol._validation import as_in_interval, as_positive
from ucontrol.exceptions import IntegrationError, InvalidParameterError, SolverError

if TYPE_CHECKING:
    from matplotlib.figure import Figure

Vector = NDArray[np.float64]
Matrix = NDArray[np.float64]
Map = Callable[[Vector], Vector]

#: Impacts allowed in one evaluation of a map before it is declared chattering.
_MAX_IMPACTS = 10_000


@dataclass(frozen=True, kw_only=True)
class ImpactSystem:
    """A periodically forced system with one impact surface.

    Attributes:
        flow: f(t, x), the smooth dynamics between impacts, shape (n,).
        flow_jacobian: ∂f/∂x (t, x), shape (n, n).
        gap: g(t, x), >= 0 away from impacts (an impact is a decreasing zero).
        gap_gradient: (∂g/∂x shape (n,), ∂g/∂t) at (t, x).
        reset: R(t, x-), the post-impact state, shape (n,).
        reset_jacobian: (∂R/∂x shape (n, n), ∂R/∂t shape (n,)) at (t, x-).
        period: Forcing period T in [s].
        rtol: Relative tolerance of solve_ivp.
        atol: Absolute tolerance of solve_ivp.
        sticking: Optional hook (t, x+) -> (t, x) or None: called after every impact, it may
            replace an accumulation of impacts (the post-impact relative velocity too small)
            by a persistent contact up to the take-off, returning the take-off state.
    """

    flow: Callable[[float, Vector], Vector]
    flow_jacobian: Callable[[float, Vector], Matrix]
    gap: Callable[[float, Vector], float]
    gap_gradient: Callable[[float, Vector], tuple[Vector, float]]
    reset: Callable[[float, Vector], Vector]
    reset_jacobian: Callable[[float, Vector], tuple[Matrix, Vector]]
    period: float
    rtol: float = 1e-12
    atol: float = 1e-14
    sticking: Callable[[float, Vector], tuple[float, Vector] | None] | None = None

    def saltation(self, t: float, x_minus: Vector) -> Matrix:
        """The saltation matrix S at an impact at (t, x-), shape (n, n)."""
        x_plus = self.reset(t, x_minus)
        R_x, R_t = self.reset_jacobian(t, x_minus)
        g_x, g_t = self.gap_gradient(t, x_minus)
        f_minus, f_plus = self.flow(t, x_minus), self.flow(t, x_plus)
        return R_x + np.outer(f_plus - R_x @ f_minus - R_t, g_x) / (g_x @ f_minus + g_t)


@dataclass(frozen=True)
class Trajectory:
    """A flow of an :class:`ImpactSystem` over an interval.

    Attributes:
        x: State at the end, shape (n,).
        jacobian: ∂x(t1)/∂x(t0) by variational equations and saltation, shape (n, n), or None.
        impacts: Times of the impacts in [s].
        impact_speeds: Approach speeds -dg/dt at the impacts, shape (impacts,).
        min_gap: Smallest gap away from the impacts (a grazing indicator).
    """

    x: Vector
    jacobian: Matrix | None
    impacts: list[float]
    impact_speeds: list[float]
    min_gap: float


def flow(
    system: ImpactSystem,
    t0: float,
    x0: Vector,
    t1: float,
    *,
    variational: bool = False,
    stop_at_impact: bool = False,
    reset: bool = True,
) -> tuple[float, Trajectory]:
    """Integrate from (t0, x0) to t1, impacts included.

    Args:
        system: The system.
        t0: Start time in [s].
        x0: Start state, shape (n,).
        t1: End time in [s].
        variational: Also integrate ∂x/∂x0 with saltation at the impacts.
        stop_at_impact: Stop at the first impact (after its reset) instead of t1.
        reset: With ``stop_at_impact``, False stops just before the reset (state x-).

    Returns:
        The end time (t1, or the impact's) and the :class:`Trajectory`.

    Raises:
        IntegrationError: solve_ivp failed or more than 10 000 impacts (chattering).
    """
    x = np.array(x0, dtype=float)
    n = x.size
    Phi = np.eye(n) if variational else None
    t = float(t0)
    impacts: list[float] = []
    speeds: list[float] = []
    min_gap = math.inf

    def rate(t: float, y: Vector) -> Vector:
        dx = system.flow(t, y[:n])
        if not variational:
            return dx
        A = system.flow_jacobian(t, y[:n])
        return np.concatenate((dx, (A @ y[n:].reshape(n, n)).ravel()))

    def event(t: float, y: Vector) -> float:
        return float(system.gap(t, y[:n]))

    event.terminal = True  # type: ignore[attr-defined]
    event.direction = -1.0  # type: ignore[attr-defined]
    while t < t1:
        if len(impacts) > _MAX_IMPACTS:
            raise IntegrationError("poincare", t, f"more than {_MAX_IMPACTS} impacts (chattering)")
        y0 = x if Phi is None else np.concatenate((x, Phi.ravel()))
        solution = solve_ivp(
            rate,
            (t, t1),
            y0,
            method="DOP853",
            rtol=system.rtol,
            atol=system.atol,
            events=event,
            dense_output=False,
        )
        if solution.status < 0:
            raise IntegrationError("poincare", t, solution.message)
        gaps = [system.gap(ti, yi[:n]) for ti, yi in zip(solution.t[1:-1], solution.y.T[1:-1])]
        min_gap = min([min_gap, *gaps])
        t = float(solution.t[-1])
        y = solution.y[:, -1]
        x = y[:n].copy()
        if Phi is not None:
            Phi = y[n:].reshape(n, n).copy()
        if solution.status != 1:
            break
        g_x, g_t = system.gap_gradient(t, x)
        speeds.append(-float(g_x @ system.flow(t, x) + g_t))
        impacts.append(t)
        if stop_at_impact and not reset:
            break
        if Phi is not None:
            Phi = system.saltation(t, x) @ Phi
        x = system.reset(t, x)
        if system.sticking is not None:
            stuck = system.sticking(t, x)
            if stuck is not None:
                if Phi is not None:
                    raise SolverError("poincare", "no saltation through a sticking phase")
                t, x = stuck
        if stop_at_impact:
            break
    return t, Trajectory(x, Phi, impacts, speeds, min_gap)


def smallest_gap(system: ImpactSystem, t0: float, x0: Vector, periods: int = 1) -> float:
    """Smallest gap over ``periods`` periods of the flow from (t0, x0), impacts ignored.

    The minimum of the gap on solve_ivp's dense output, refined by a bounded scalar search:
    the grazing indicator of a non-impacting orbit (it touches the surface at 0).
    """
    from scipy.optimize import minimize_scalar

    t1 = t0 + periods * system.period
    solution = solve_ivp(
        system.flow,
        (t0, t1),
        np.asarray(x0, dtype=float),
        method="DOP853",
        rtol=system.rtol,
        atol=system.atol,
        dense_output=True,
    )
    times = np.linspace(t0, t1, 400 * periods + 1)
    gaps = np.array([system.gap(t, solution.sol(t)) for t in times])
    i = int(np.argmin(gaps))
    low, high = times[max(i - 1, 0)], times[min(i + 1, times.size - 1)]
    best = minimize_scalar(
        lambda t: system.gap(t, solution.sol(t)),
        bounds=(low, high),
        method="bounded",
        options={"xatol": 1e-13 * max(1.0, abs(t1))},
    )
    return float(min(best.fun, gaps[i]))


def without_impacts(system: ImpactSystem) -> ImpactSystem:
    """The same flow with the impact surface removed.

    Its periodic orbits are the non-impacting ones, followed through their grazing (where
    :func:`smallest_gap` of the original system crosses 0) even when no impacting orbit
    continues them.
    """
    return replace(system, gap=lambda t, x: 1.0, sticking=None)


def stroboscopic_map(
    system: ImpactSystem, t0: float = 0.0, periods: int = 1
) -> Callable[[Vector], Vector]:
    """x(t0) -> x(t0 + periods T)."""

    def P(x: Vector) -> Vector:
        return flow(system, t0, x, t0 + periods * system.period)[1].x

    return P


def stroboscopic_jacobian(
    system: ImpactSystem, x: Vector, t0: float = 0.0, periods: int = 1
) -> Matrix:
    """∂x(t0 + periods T)/∂x(t0) by the variational equations and saltation matrices."""
    trajectory = flow(system, t0, x, t0 + periods * system.period, variational=True)[1]
    assert trajectory.jacobian is not None
    return trajectory.jacobian


def stroboscopic_solver(
    system_at: Callable[[float], ImpactSystem], *, period: int = 1
) -> Callable[[float, Vector], FixedPoint]:
    """The ``solve`` of :func:`continuation` for the period-``period`` orbit of a system.

    Args:
        system_at: The system at a parameter value (e.g. ``lambda w:
            impact_oscillator(frequency=w, ...)``).
        period: Forcing periods of the orbit (k of :func:`fixed_point`).

    Returns:
        (parameter, guess) -> the fixed point of the stroboscopic map x(0) -> x(T) at that
        parameter, by Newton with the Jacobian of :func:`stroboscopic_jacobian` (variational
        equations and saltation matrices).
    """

    def solve(parameter: float, guess: Vector) -> FixedPoint:
        system = system_at(parameter)
        return fixed_point(
            stroboscopic_map(system),
            guess,
            period=period,
            jacobian=lambda z: stroboscopic_jacobian(system, z),
        )

    return solve


def impact_map(system: ImpactSystem, horizon: float | None = None) -> Callable[[Vector], Vector]:
    """The impact map (t_k, x_k+) -> (t_{k+1}, x_{k+1}+), to the next impact; shape (n + 1,).

    Raises:
        InvalidParameterError: No impact within ``horizon`` (default 100 periods): the
            section is never crossed.
    """
    limit = 100.0 * system.period if horizon is None else horizon

    def P(z: Vector) -> Vector:
        t, trajectory = flow(system, z[0], z[1:], z[0] + limit, stop_at_impact=True)
        if not trajectory.impacts:
            raise InvalidParameterError(
                "section", f"no impact from t = {z[0]:.6g} s within {limit:.6g} s", "crossed"
            )
        return np.concatenate(([t], trajectory.x))

    return P


def impact_map_jacobian(system: ImpactSystem, z: Vector) -> Matrix:
    """Jacobian of :func:`impact_map` at z by variational equations, shape (n + 1, n + 1).

    With Φ the flow's sensitivity from (t_k, x_k) to the impact at t_{k+1}:
    dt' = -g_x Φ (dx - f_k dt) / (g_x f⁻ + g_t), dx⁻ = f⁻ dt' + Φ (dx - f_k dt) and
    dx⁺ = R_x dx⁻ + R_t dt'.
    """
    t0, x0 = float(z[0]), np.asarray(z[1:], dtype=float)
    n = x0.size
    t1, trajectory = flow(
        system,
        t0,
        x0,
        t0 + 100.0 * system.period,
        variational=True,
        stop_at_impact=True,
        reset=False,
    )
    x_minus, Phi = trajectory.x, trajectory.jacobian
    assert Phi is not None
    if not trajectory.impacts:
        raise InvalidParameterError("section", f"no impact from t = {t0:.6g} s", "crossed")
    f_k = system.flow(t0, x0)
    f_minus = system.flow(t1, x_minus)
    g_x, g_t = system.gap_gradient(t1, x_minus)
    R_x, R_t = system.reset_jacobian(t1, x_minus)
    B = np.hstack(((-Phi @ f_k)[:, None], Phi))  # ∂x(t1 fixed)/∂(t0, x0), shape (n, n + 1)
    dt = -(g_x @ B) / (g_x @ f_minus + g_t)  # shape (n + 1,)
    dx_minus = np.outer(f_minus, dt) + B
    jacobian = np.zeros((n + 1, n + 1))
    jacobian[0] = dt
    jacobian[1:] = R_x @ dx_minus + np.outer(R_t, dt)
    return jacobian


def finite_difference_jacobian(P: Map, z: Vector, step: float = 1e-6) -> Matrix:
    """Central differences of a map at z, relative steps; shape (len(P(z)), z.size)."""
    z = np.asarray(z, dtype=float)
    columns = []
    for i in range(z.size):
        h = step * max(1.0, abs(z[i]))
        plus, minus = z.copy(), z.copy()
        plus[i] += h
        minus[i] -= h
        columns.append((P(plus) - P(minus)) / (2.0 * h))
    return np.array(columns).T


@dataclass(frozen=True)
class FixedPoint:
    """A fixed point of a Poincaré map (or of its k-th iterate).

    Attributes:
        z: The point.
        jacobian: The map's Jacobian there (of the k-th iterate).
        multipliers: Floquet multipliers, sorted by decreasing modulus.
        residual: ‖P^k(z) - z - shift‖ at the end.
        iterations: Newton iterations.
    """

    z: Vector
    jacobian: Matrix
    multipliers: NDArray[np.complex128]
    residual: float
    iterations: int

    @property
    def stable(self) -> bool:
        """Whether every multiplier is inside the unit circle."""
        return bool(np.max(np.abs(self.multipliers)) < 1.0)


def fixed_point(
    P: Map,
    z0: Vector,
    *,
    period: int = 1,
    shift: Vector | None = None,
    jacobian: Callable[[Vector], Matrix] | None = None,
    tol: float = 1e-12,
    max_iter: int = 30,
    drop_trivial: int = 0,
) -> FixedPoint:
    r"""Newton on :math:`P^k(z) - z - \text{shift} = 0`.

    Args:
        P: The map.
        z0: First guess.
        period: k, the number of iterates of the orbit.
        shift: Constant added by k iterates on a periodic orbit (the time coordinate of an
            impact map grows by the orbit's period); zero by default.
        jacobian: Jacobian of P (one iterate); default central finite differences.
        tol: Residual at which Newton stops.
        max_iter: Newton iterations before :class:`SolverError`.
        drop_trivial: Multipliers closest to 0 to drop (1 for an impact map's section).

    Raises:
        SolverError: Newton did not converge.
    """
    z = np.array(z0, dtype=float)
    shift_vector = np.zeros(z.size) if shift is None else np.asarray(shift, dtype=float)

    def iterate(z: Vector) -> tuple[Vector, Matrix]:
        x, Jk = z, np.eye(z.size)
        for _ in range(period):
            Jx = jacobian(x) if jacobian is not None else finite_difference_jacobian(P, x)
            Jk = Jx @ Jk
            x = P(x)
        return x, Jk

    residual = math.inf
    for iteration in range(1, max_iter + 1):
        image, Jk = iterate(z)
        G = image - z - shift_vector
        residual = float(np.linalg.norm(G))
        if residual <= tol * max(1.0, float(np.linalg.norm(z))):
            return _fixed(z, Jk, residual, iteration, drop_trivial)
        try:
            step = np.linalg.solve(Jk - np.eye(z.size), G)
        except np.linalg.LinAlgError as error:
            raise SolverError("poincare newton", "singular P' - I", residual) from error
        z = _damped(lambda z: _residual(P, z, period, shift_vector), z, step, residual)
    raise SolverError("poincare newton", f"no convergence in {max_iter} iterations", residual)


def _residual(P: Map, z: Vector, period: int, shift: Vector) -> float:
    x = z
    for _ in range(period):
        x = P(x)
    return float(np.linalg.norm(x - z - shift))


def _damped(residual: Callable[[Vector], float], z: Vector, step: Vector, r0: float) -> Vector:
    """Damped Newton: z - λ step, the largest λ in 1, 1/2, ... 1/64 lowering the residual.

    Near a grazing the map is only continuous (its Jacobian has a square-root singularity),
    where full Newton steps may cycle. A trial whose map fails counts as no decrease.
    """
    weight = 1.0
    for _ in range(7):
        trial = z - weight * step
        try:
            if residual(trial) < r0:
                return trial
        except (IntegrationError, InvalidParameterError):
            pass
        weight /= 2.0
    return z - step


def _fixed(z: Vector, Jk: Matrix, residual: float, iterations: int, drop: int) -> FixedPoint:
    multipliers = np.asarray(np.linalg.eigvals(Jk), dtype=np.complex128)
    multipliers = multipliers[np.argsort(-np.abs(multipliers))]
    if drop:
        multipliers = multipliers[:-drop]
    return FixedPoint(z, Jk, multipliers, residual, iterations)


@dataclass(frozen=True)
class Bifurcation:
    """A bifurcation located on a branch.

    Attributes:
        kind: ``"period_doubling"`` (a multiplier crosses -1), ``"fold"`` (+1), ``"torus"``
            (a complex pair crosses the unit circle) or ``"grazing"``.
        parameter: The parameter value, refined by bisection.
        z: The fixed point there.
    """

    kind: str
    parameter: float
    z: Vector


@dataclass(frozen=True)
class Branch:
    """A branch of fixed points followed in one parameter.

    Attributes:
        parameters: Parameter values reached, shape (k,).
        points: Fixed points, shape (k, dim).
        multipliers: Their Floquet multipliers, shape (k, n).
        bifurcations: Located bifurcations, in the order met.
        stopped: Why the continuation stopped early ("" when it reached the end).
    """

    parameters: Vector
    points: Matrix
    multipliers: NDArray[np.complex128]
    bifurcations: list[Bifurcation] = field(default_factory=list)
    stopped: str = ""


def continuation(
    solve: Callable[[float, Vector], FixedPoint],
    parameters: Vector,
    z0: Vector,
    *,
    grazing: Callable[[float, Vector], float] | None = None,
    tol: float = 1e-12,
    stop_at: tuple[str, ...] = (),
    max_halvings: int = 8,
) -> Branch:
    """Natural-parameter continuation with secant prediction and bisection of bifurcations.

    Args:
        solve: (parameter, guess) -> :class:`FixedPoint` (e.g. :func:`fixed_point` on the map
            of the system at that parameter).
        parameters: Parameter values to visit, monotone, shape (k,).
        z0: Guess of the fixed point at ``parameters[0]``.
        grazing: (parameter, z) -> a number whose sign change along the branch marks a
            grazing (e.g. the smallest gap of the orbit minus 0, or its impact speed).
        tol: Parameter resolution of the bisections.
        stop_at: Bifurcation kinds at which to stop.
        max_halvings: Halvings of a step whose Newton fails before the continuation stops.
    """
    params: list[float] = []
    points: list[Vector] = []
    multipliers: list[NDArray[np.complex128]] = []
    found: list[Bifurcation] = []
    previous: tuple[float, FixedPoint, float | None] | None = None
    z = np.asarray(z0, dtype=float)
    stopped = ""
    targets = list(np.asarray(parameters, dtype=float))
    halvings = 0
    while targets:
        mu = targets[0]
        guess = z
        if len(points) >= 2 and halvings == 0:
            slope = (points[-1] - points[-2]) / (params[-1] - params[-2])
            guess = points[-1] + slope * (mu - params[-1])
        try:
            point = solve(float(mu), guess)
        except (SolverError, IntegrationError, InvalidParameterError) as error:
            if not params or halvings >= max_halvings:
                stopped = f"no fixed point at {mu:.9g}: {error}"
                break
            targets.insert(0, 0.5 * (params[-1] + mu))  # retry half-way, no prediction
            halvings += 1
            continue
        targets.pop(0)
        halvings = 0
        indicator = grazing(float(mu), point.z) if grazing is not None else None
        if previous is not None:
            new = _locate(solve, previous, (float(mu), point, indicator), grazing, tol)
            found += new
            if any(b.kind in stop_at for b in new):
                stopped = new[0].kind
                params.append(float(mu))
                points.append(point.z)
                multipliers.append(point.multipliers)
                break
        params.append(float(mu))
        points.append(point.z)
        multipliers.append(point.multipliers)
        previous = (float(mu), point, indicator)
        z = point.z
    width = max((m.size for m in multipliers), default=0)
    table = np.full((len(multipliers), width), np.nan, dtype=complex)
    for i, m in enumerate(multipliers):
        table[i, : m.size] = m
    return Branch(np.array(params), np.array(points), table, found, stopped)


def _indicators(point: FixedPoint) -> dict[str, float]:
    """Quantities whose sign changes mark the bifurcations of a fixed point.

    det(I + P') changes sign when a real multiplier crosses -1 (complex pairs contribute
    |1 + λ|² > 0), det(I - P') when one crosses +1; a complex pair leaving the unit circle
    changes the sign of 1 - |λ|.
    """
    identity = np.eye(point.jacobian.shape[0])
    pairs = point.multipliers[np.abs(point.multipliers.imag) > 1e-9]
    return {
        "period_doubling": float(np.linalg.det(identity + point.jacobian)),
        "fold": float(np.linalg.det(identity - point.jacobian)),
        "torus": float(1.0 - np.max(np.abs(pairs))) if pairs.size else math.nan,
    }


def _locate(
    solve: Callable[[float, Vector], FixedPoint],
    a: tuple[float, FixedPoint, float | None],
    b: tuple[float, FixedPoint, float | None],
    grazing: Callable[[float, Vector], float] | None,
    tol: float,
) -> list[Bifurcation]:
    """Bifurcations between two consecutive points of a branch, bisected to ``tol``."""
    found = []
    ia, ib = _indicators(a[1]), _indicators(b[1])
    for kind in ("period_doubling", "fold", "torus"):
        if ia[kind] * ib[kind] < 0:  # False with NaN: no complex pair on one side
            found.append(_bisect(solve, a, b, _indicator_of(kind), kind, tol))
    if grazing is not None and a[2] is not None and b[2] is not None and a[2] * b[2] < 0:
        found.append(_bisect(solve, a, b, None, "grazing", tol, lambda mu, p: grazing(mu, p.z)))
    return sorted(found, key=lambda bif: bif.parameter * np.sign(b[0] - a[0]))


def _indicator_of(kind: str) -> Callable[[FixedPoint], float]:
    return lambda point: _indicators(point)[kind]


def _bisect(
    solve: Callable[[float, Vector], FixedPoint],
    a: tuple[float, FixedPoint, float | None],
    b: tuple[float, FixedPoint, float | None],
    indicator: Callable[[FixedPoint], float] | None,
    kind: str,
    tol: float,
    indicator_at: Callable[[float, FixedPoint], float] | None = None,
) -> Bifurcation:
    """Secant-bisection (Illinois) of an indicator's sign change between a and b."""

    def value(mu: float, point: FixedPoint) -> float:
        if indicator_at is not None:
            return indicator_at(mu, point)
        assert indicator is not None
        return indicator(point)

    mu_a, pa = a[0], a[1]
    mu_b, pb = b[0], b[1]
    fa, fb = value(mu_a, pa), value(mu_b, pb)
    side = 0
    point = pa
    for _ in range(200):
        if abs(mu_b - mu_a) <= tol * max(1.0, abs(mu_a)):
            break
        mu = (mu_a * fb - mu_b * fa) / (fb - fa)
        if not min(mu_a, mu_b) < mu < max(mu_a, mu_b):
            mu = 0.5 * (mu_a + mu_b)
        weight = (mu - mu_a) / (mu_b - mu_a)
        point = solve(mu, pa.z + weight * (pb.z - pa.z))
        f = value(mu, point)
        if f == 0.0:
            mu_a = mu_b = mu
            break
        if f * fa < 0:
            mu_b, pb, fb = mu, point, f
            if side == -1:
                fa /= 2.0
            side = -1
        else:
            mu_a, pa, fa = mu, point, f
            if side == 1:
                fb /= 2.0
            side = 1
    return Bifurcation(kind, 0.5 * (mu_a + mu_b), point.z)


def orbit_diagram(
    P: Callable[[float, Vector], Vector],
    parameters: Vector,
    z0: Vector,
    *,
    coordinate: Callable[[Vector], float],
    transient: int = 200,
    keep: int = 64,
) -> tuple[Vector, Vector]:
    """Iterate P(parameter, z) past a transient and keep a coordinate of the next iterates.

    The final state at one parameter seeds the next (following the attractor). Parameters where
    the iteration fails (chattering, no impact) are skipped.

    Returns:
        Parameter values and coordinates, both shape (k,), for a scatter plot.
    """
    xs: list[float] = []
    ys: list[float] = []
    z = np.asarray(z0, dtype=float)
    for mu in np.asarray(parameters, dtype=float):
        try:
            for _ in range(transient):
                z = P(float(mu), z)
            for _ in range(keep):
                z = P(float(mu), z)
                xs.append(float(mu))
                ys.append(coordinate(z))
        except (IntegrationError, InvalidParameterError, SolverError):
            z = np.asarray(z0, dtype=float)
    return np.array(xs), np.array(ys)


def bifurcation_figure(
    diagram: tuple[Vector, Vector],
    branches: list[Branch] | None = None,
    *,
    coordinate: Callable[[Vector], float] | None = None,
    xlabel: str = "parameter",
    ylabel: str = "coordinate",
    title: str = "",
) -> Figure:
    """Orbit diagram (points), followed branches (dashed where unstable), bifurcations.

    Bifurcations are drawn as vertical dotted lines labelled with their parameter.
    """
    from matplotlib.figure import Figure  # lazy: matplotlib only for figures

    figure = Figure(figsize=(7.0, 4.2), layout="constrained")
    axes = figure.add_subplot()
    axes.plot(diagram[0], diagram[1], ",", color="black", alpha=0.6, label="orbit diagram")
    colours = {"period_doubling": "tab:red", "grazing": "tab:blue", "fold": "tab:green"}
    for branch in branches or []:
        if coordinate is None or branch.parameters.size == 0:
            continue
        values = np.array([coordinate(z) for z in branch.points])
        stable = np.max(np.abs(branch.multipliers), axis=1) < 1.0
        axes.plot(
            np.where(stable, branch.parameters, np.nan), values, "-", color="tab:orange", lw=1.2
        )
        axes.plot(
            np.where(stable, np.nan, branch.parameters), values, "--", color="tab:orange", lw=1.0
        )
        for bifurcation in branch.bifurcations:
            axes.axvline(
                bifurcation.parameter,
                color=colours.get(bifurcation.kind, "grey"),
                lw=0.8,
                ls=":",
                label=f"{bifurcation.kind.replace('_', ' ')} {bifurcation.parameter:.6g}",
            )
    axes.set_xlabel(xlabel)
    axes.set_ylabel(ylabel)
    if title:
        axes.set_title(title)
    axes.legend(loc="best", fontsize="small")
    return figure


# --- the ball on a vibrating table ----------------------------------------------------------


def vibrating_table_ball(
    *,
    amplitude: float,
    frequency: float,
    restitution: float,
    gravity: float = 9.81,
    stick_velocity: float = 0.0,
) -> ImpactSystem:
    r"""A ball bouncing on a table at height :math:`s(t) = A \sin \omega t`.

    State x = (y, ẏ) of the ball [m, m/s]; gap :math:`y - s(t)`; Newton's law with the table's
    velocity, :math:`\dot y^+ = -e \dot y^- + (1 + e)\dot s(t)`.

    Args:
        amplitude: A in [m].
        frequency: ω in [rad/s].
        restitution: e in [0, 1].
        gravity: g in [m/s²].
        stick_velocity: Relative rebound speed in [m/s] below which the ball sticks to the
            table until the table's acceleration falls to -g (0: never; needs Aω² > g).
    """
    A = as_positive("amplitude", amplitude)
    w = as_positive("frequency", frequency)
    e = as_in_interval("restitution", restitution, 0.0, 1.0)
    g = as_positive("gravity", gravity)

    def s(t: float) -> tuple[float, float, float]:
        return A * math.sin(w * t), A * w * math.cos(w * t), -A * w * w * math.sin(w * t)

    def sticking(t: float, x: Vector) -> tuple[float, Vector] | None:
        _, ds, _ = s(t)
        gamma = A * w * w / g
        theta = (w * t) % (2.0 * math.pi)
        if x[1] - ds > stick_velocity or gamma <= 1.0 or math.sin(theta) * gamma > 1.0:
            return None
        # stuck until the table's acceleration -A ω² sin(ωt) falls to -g, sin(ωt) increasing
        take_off = math.asin(1.0 / gamma)
        t_off = t + ((take_off - theta) % (2.0 * math.pi)) / w
        y, dy, _ = s(t_off)
        return t_off, np.array([y, dy])

    return ImpactSystem(
        flow=lambda t, x: np.array([x[1], -g]),
        flow_jacobian=lambda t, x: np.array([[0.0, 1.0], [0.0, 0.0]]),
        gap=lambda t, x: float(x[0] - A * math.sin(w * t)),
        gap_gradient=lambda t, x: (np.array([1.0, 0.0]), -A * w * math.cos(w * t)),
        reset=lambda t, x: np.array([x[0], -e * x[1] + (1.0 + e) * A * w * math.cos(w * t)]),
        reset_jacobian=lambda t, x: (
            np.diag([1.0, -e]),
            np.array([0.0, -(1.0 + e) * A * w * w * math.sin(w * t)]),
        ),
        period=2.0 * math.pi / w,
        sticking=sticking if stick_velocity > 0.0 else None,
    )


def vibrating_table_period_one(
    *, amplitude: float, frequency: float, restitution: float, gravity: float = 9.81, n: int = 1
) -> tuple[float, float]:
    r"""The stable period-n orbit of the ball on the vibrating table (one impact every n periods).

    Flight time :math:`T = 2\pi n/\omega` between impacts at the same phase: take-off speed
    :math:`gT/2`, landing speed :math:`-gT/2`, and Newton's law gives
    :math:`\cos\varphi^* = \pi n g (1 - e) / ((1 + e) A \omega^2)`; the stable solution has
    :math:`\sin\varphi^* > 0` (Holmes 1982; Luck & Mehta 1993).

    Returns:
        Impact phase φ* in [0, π] [rad] and post-impact ball velocity gT/2 in [m/s].

    Raises:
        InvalidParameterError: The amplitude is below the existence threshold.
    """
    g, A, w, e = gravity, amplitude, frequency, restitution
    T = 2.0 * math.pi * n / w
    cosine = math.pi * n * g * (1.0 - e) / ((1.0 + e) * A * w * w)
    if cosine > 1.0:
        raise InvalidParameterError(
            "amplitude", amplitude, f">= {A * cosine:.6g} m for a period-{n} orbit"
        )
    return math.acos(cosine), g * T / 2.0


def vibrating_table_flip_amplitude(
    *, frequency: float, restitution: float, gravity: float = 9.81, n: int = 1
) -> float:
    r"""Amplitude in [m] at which the period-n orbit loses stability by period doubling.

    The impact map's Jacobian at the orbit has trace :math:`1 + e^2 - (1+e)^2 \Gamma \sin\varphi^*`
    and determinant :math:`e^2` (:math:`\Gamma = A\omega^2/g`); a multiplier at -1 gives
    :math:`\Gamma^2 = (\pi n (1-e)/(1+e))^2 + (2 (1 + e^2)/(1+e)^2)^2`.
    """
    e = restitution
    gamma = math.hypot(math.pi * n * (1.0 - e) / (1.0 + e), 2.0 * (1.0 + e * e) / (1.0 + e) ** 2)
    return gamma * gravity / frequency**2


# --- the linear impact oscillator -------------------------------------------------------------


def impact_oscillator(
    *,
    mass: float,
    damping: float,
    stiffness: float,
    force: float,
    frequency: float,
    stop: float,
    restitution: float,
    stick_velocity: float = 0.0,
) -> ImpactSystem:
    r"""The impact oscillator m ẍ + c ẋ + k x = F cos ωt, x <= σ, stop x = σ: ẋ+ = -r ẋ-.

    State x = (x, ẋ) [m, m/s]; gap σ - x. With ``stick_velocity`` > 0 [m/s], a rebound slower
    than it ends an accumulation of impacts: the mass rests on the stop until the net force
    :math:`F\cos\omega t - k\sigma` turns away from it.
    """
    m = as_positive("mass", mass)
    c = float(damping)
    if c < 0.0:
        raise InvalidParameterError("damping", damping, ">= 0")
    k = as_positive("stiffness", stiffness)
    w = as_positive("frequency", frequency)
    r = as_in_interval("restitution", restitution, 0.0, 1.0)
    F, sigma = float(force), float(stop)

    def sticking(t: float, x: Vector) -> tuple[float, Vector] | None:
        if abs(x[1]) > stick_velocity or F * math.cos(w * t) - k * sigma < 0.0:
            return None
        if abs(k * sigma) >= abs(F):
            raise IntegrationError("poincare", t, "the mass rests on the stop for ever")
        release = math.acos(k * sigma / F)  # phase where the net force turns away, decreasing
        phase = (w * t) % (2.0 * math.pi)
        return t + ((release - phase) % (2.0 * math.pi)) / w, np.array([sigma, 0.0])

    return ImpactSystem(
        flow=lambda t, x: np.array([x[1], (F * math.cos(w * t) - c * x[1] - k * x[0]) / m]),
        flow_jacobian=lambda t, x: np.array([[0.0, 1.0], [-k / m, -c / m]]),
        gap=lambda t, x: float(sigma - x[0]),
        gap_gradient=lambda t, x: (np.array([-1.0, 0.0]), 0.0),
        reset=lambda t, x: np.array([x[0], -r * x[1]]),
        reset_jacobian=lambda t, x: (np.diag([1.0, -r]), np.zeros(2)),
        period=2.0 * math.pi / w,
        sticking=sticking if stick_velocity > 0.0 else None,
    )


def free_response_amplitude(
    *, mass: float, damping: float, stiffness: float, force: float, frequency: float
) -> float:
    """Amplitude in [m] of the steady response of m ẍ + c ẋ + k x = F cos ωt without the stop."""
    return abs(force) / math.hypot(stiffness - mass * frequency**2, damping * frequency)


@dataclass(frozen=True, kw_only=True)
class SinusoidalForcing:
    r"""A controller applying a spring, a damper and a sinusoidal force to one joint.

    :math:`u = -k (q_j - q_\text{rest}) - c\,v_j + F\cos(\omega t + \varphi)` on joint index j
    (0 elsewhere): the impact oscillator as a scene (``robots/impact_oscillator.toml``) run by
    :func:`ucontrol.simulate` with the event-driven integrator. The force is held over each
    control period (zero-order hold), an O(h) difference from the continuous oscillator.

    Attributes:
        stiffness: k in [N/m].
        damping: c in [N s/m].
        force: F in [N].
        frequency: ω in [rad/s].
        phase: φ in [rad].
        rest: q_rest in [m].
        index: j, the velocity index of the joint.
        nu: Size of the returned torque vector.
    """

    stiffness: float
    damping: float
    force: float
    frequency: float
    phase: float = 0.0
    rest: float = 0.0
    index: int = 0
    nu: int = 1

    def __call__(self, t: float, q: Vector, v: Vector, contacts: object) -> Vector:
        """Generalized force at t, shape (nu,)."""
        u = np.zeros(self.nu)
        u[self.index] = (
            -self.stiffness * (q[self.index] - self.rest)
            - self.damping * v[self.index]
            + self.force * math.cos(self.frequency * t + self.phase)
        )
        return u
