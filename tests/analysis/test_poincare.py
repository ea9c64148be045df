"""Poincaré maps, periodic orbits and Floquet multipliers against analytic references.

References: the ball on a sinusoidally vibrating table (period-1 orbit and its period-doubling
amplitude in closed form, Holmes 1982, Luck & Mehta 1993, derived in
docs/stability.md), the linear impact oscillator whose flow between impacts is a
matrix exponential (its period-1 orbit solved here with scipy.optimize.fsolve on the exact
flow, and its monodromy built by hand with the closed-form saltation matrix), the grazing
amplitude of the oscillator's free response, and finite differences of the maps.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.optimize import fsolve

from ucontrol.analysis import poincare as pc
from ucontrol.exceptions import InvalidParameterError

_G, _W, _E = 9.81, 2.0 * math.pi, 0.8  # gravity [m/s²], table frequency [rad/s], restitution
_T = 2.0 * math.pi / _W


def ball_fixed_point(amplitude: float, z0: np.ndarray) -> pc.FixedPoint:
    system = pc.vibrating_table_ball(amplitude=amplitude, frequency=_W, restitution=_E)
    return pc.fixed_point(
        pc.impact_map(system),
        z0,
        shift=np.array([_T, 0.0, 0.0]),
        jacobian=lambda z: pc.impact_map_jacobian(system, z),
        drop_trivial=1,
    )


def analytic_ball_orbit(amplitude: float) -> np.ndarray:
    phase, speed = pc.vibrating_table_period_one(amplitude=amplitude, frequency=_W, restitution=_E)
    return np.array([phase / _W, amplitude * math.sin(phase), speed])


def test_ball_period_one_orbit_matches_analytic_fixed_point() -> None:
    A = 0.8 * pc.vibrating_table_flip_amplitude(frequency=_W, restitution=_E)
    exact = analytic_ball_orbit(A)
    found = ball_fixed_point(A, exact + np.array([0.01, 0.0, 0.05]))
    assert np.max(np.abs(found.z - exact)) <= 1e-10
    # multipliers: trace 1 + e² - (1+e)² Γ sin φ*, determinant e²
    gamma = A * _W**2 / _G
    trace = 1 + _E**2 - (1 + _E) ** 2 * gamma * math.sin(exact[0] * _W)
    expected = np.roots([1.0, -trace, _E**2])
    assert np.max(np.abs(np.sort_complex(found.multipliers) - np.sort_complex(expected))) <= 1e-9
    assert found.stable


def test_ball_jacobians_saltation_against_finite_differences() -> None:
    A = 0.9 * pc.vibrating_table_flip_amplitude(frequency=_W, restitution=_E)
    system = pc.vibrating_table_ball(amplitude=A, frequency=_W, restitution=_E)
    z = analytic_ball_orbit(A) + np.array([0.003, 0.0, -0.02])
    z[1] = A * math.sin(_W * z[0])  # on the section
    by_saltation = pc.impact_map_jacobian(system, z)
    by_differences = pc.finite_difference_jacobian(pc.impact_map(system), z)
    assert np.max(np.abs(by_saltation - by_differences)) <= 1e-6
    t0 = z[0] + 0.4  # in flight
    x0 = pc.flow(system, z[0], z[1:], t0)[1].x
    by_saltation = pc.stroboscopic_jacobian(system, x0, t0=t0, periods=2)
    strobe = pc.stroboscopic_map(system, t0=t0, periods=2)
    assert np.max(np.abs(by_saltation - pc.finite_difference_jacobian(strobe, x0))) <= 1e-6


def test_ball_period_doubling_amplitude_found_by_continuation() -> None:
    A_flip = pc.vibrating_table_flip_amplitude(frequency=_W, restitution=_E)
    A0 = 0.7 * A_flip
    branch = pc.continuation(
        ball_fixed_point, np.linspace(A0, 1.2 * A_flip, 8), analytic_ball_orbit(A0), tol=1e-13
    )
    flips = [b for b in branch.bifurcations if b.kind == "period_doubling"]
    assert len(flips) == 1
    assert abs(flips[0].parameter / A_flip - 1.0) <= 1e-6
    stable = np.max(np.abs(branch.multipliers), axis=1) < 1.0
    assert np.all(stable[branch.parameters < A_flip]) and not np.any(
        stable[branch.parameters > A_flip]
    )


def test_ball_below_existence_threshold_is_refused() -> None:
    with pytest.raises(InvalidParameterError, match="amplitude"):
        pc.vibrating_table_period_one(amplitude=1e-3, frequency=_W, restitution=_E)


def test_section_never_crossed_is_refused() -> None:
    # a ball thrown up faster than escape over the horizon: no impact within 100 periods
    system = pc.vibrating_table_ball(amplitude=0.01, frequency=_W, restitution=_E, gravity=1e-3)
    with pytest.raises(InvalidParameterError, match="section"):
        pc.impact_map(system)(np.array([0.0, 0.0, 5.0]))


# --- impact oscillator ----------------------------------------------------------------------

_OSCILLATOR = {
    "mass": 1.0,
    "damping": 0.05,
    "stiffness": 1.0,
    "force": 1.0,
    "stop": 0.0,
    "restitution": 0.8,
}


def exact_flow(w: float, t0: float, x0: np.ndarray, t1: float) -> np.ndarray:
    """Flow of m ẍ + c ẋ + k x = F cos ωt from (t0, x0) to t1: particular + expm homogeneous."""
    m, c, k, F = (_OSCILLATOR[key] for key in ("mass", "damping", "stiffness", "force"))
    X = F / (k - m * w**2 + 1j * c * w)  # complex amplitude of the particular solution [m]

    def particular(t: float) -> np.ndarray:
        phasor = X * np.exp(1j * w * t)
        return np.array([phasor.real, (1j * w * phasor).real])

    A = np.array([[0.0, 1.0], [-k / m, -c / m]])
    return particular(t1) + expm(A * (t1 - t0)) @ (x0 - particular(t0))


def analytic_period_one(w: float, guess: tuple[float, float]) -> tuple[float, float, np.ndarray]:
    """Impact time t*, pre-impact speed v- and Floquet multipliers of the period-1 orbit.

    Solves x(t* + T) = (σ, v-) from (σ, -r v-) at t* with the exact flow; the monodromy from
    just after the impact is S expm(A T), S = [[-r, 0], [(a+ + r a-)/v-, -r]].
    """
    m, c, k, F = (_OSCILLATOR[key] for key in ("mass", "damping", "stiffness", "force"))
    sigma, r, T = _OSCILLATOR["stop"], _OSCILLATOR["restitution"], 2 * math.pi / w

    def equations(unknowns: np.ndarray) -> np.ndarray:
        t, v = unknowns
        return exact_flow(w, t, np.array([sigma, -r * v]), t + T) - np.array([sigma, v])

    t_star, v_minus = fsolve(equations, guess, xtol=1e-13)

    def acceleration(t: float, v: float) -> float:
        return (F * math.cos(w * t) - c * v - k * sigma) / m

    a_minus, a_plus = acceleration(t_star, v_minus), acceleration(t_star, -r * v_minus)
    S = np.array([[-r, 0.0], [(a_plus + r * a_minus) / v_minus, -r]])
    A = np.array([[0.0, 1.0], [-k / m, -c / m]])
    return t_star, v_minus, np.linalg.eigvals(S @ expm(A * T))


#: The period-1 orbit (x, ẋ) at t = 0 of the oscillator forced at ω: (ω, guess) -> FixedPoint.
oscillator_fixed_point = pc.stroboscopic_solver(
    lambda w: pc.impact_oscillator(frequency=w, **_OSCILLATOR)
)


def test_oscillator_period_one_multipliers_against_exact_flow() -> None:
    w = 2.4
    system = pc.impact_oscillator(frequency=w, **_OSCILLATOR)
    found = oscillator_fixed_point(w, np.array([-1.0, 0.1]))
    trajectory = pc.flow(system, 0.0, found.z, system.period)[1]
    assert len(trajectory.impacts) == 1
    t_star = trajectory.impacts[0]
    v_minus = trajectory.impact_speeds[0] * -1.0  # gap σ - x: approach speed = ẋ
    t_ref, v_ref, multipliers = analytic_period_one(w, (t_star, -v_minus))
    assert abs(t_ref - t_star) <= 1e-9 and abs(abs(v_ref) - abs(v_minus)) <= 1e-9
    assert np.max(np.abs(np.sort_complex(found.multipliers) - np.sort_complex(multipliers))) <= 1e-8
    by_differences = np.linalg.eigvals(
        pc.finite_difference_jacobian(pc.stroboscopic_map(system), found.z)
    )
    assert np.max(np.abs(np.sort_complex(by_differences) - np.sort_complex(multipliers))) <= 1e-6
    assert found.stable


def test_oscillator_period_doubling_in_frequency() -> None:
    branch = pc.continuation(
        oscillator_fixed_point,
        np.linspace(2.4, 2.8, 5),
        np.array([-0.997, 0.1039]),
        stop_at=("period_doubling",),
    )
    flip = branch.bifurcations[0]
    assert flip.kind == "period_doubling" and 2.6 < flip.parameter < 2.7
    # the multiplier is -1 there, by finite differences of the stroboscopic map
    system = pc.impact_oscillator(frequency=flip.parameter, **_OSCILLATOR)
    point = oscillator_fixed_point(flip.parameter, flip.z)
    by_differences = np.linalg.eigvals(
        pc.finite_difference_jacobian(pc.stroboscopic_map(system), point.z)
    )
    assert np.min(np.abs(by_differences + 1.0)) <= 1e-5
    # just beyond: a stable period-2 orbit distinct from the now unstable period-1 orbit
    w = flip.parameter + 0.02
    system = pc.impact_oscillator(frequency=w, **_OSCILLATOR)
    P = pc.stroboscopic_map(system)
    x = point.z + np.array([0.01, 0.0])
    for _ in range(60):
        x = P(x)
    orbit = pc.stroboscopic_solver(
        lambda w: pc.impact_oscillator(frequency=w, **_OSCILLATOR), period=2
    )(w, x)
    assert np.linalg.norm(P(orbit.z) - orbit.z) > 1e-3
    assert orbit.stable
    assert not oscillator_fixed_point(w, point.z).stable


def test_oscillator_grazing_at_free_response_amplitude() -> None:
    """Stop at σ = 0.5 m: the non-impacting orbit grazes when its amplitude reaches σ.

    Beyond, no period-1 impacting orbit continues it (Nordmark's square-root map): the
    non-impacting orbit is followed with the stop removed and its smallest gap watched.
    """
    w, sigma = 0.8, 0.5
    parameters = {**_OSCILLATOR, "stop": sigma}

    def system_at(force: float) -> pc.ImpactSystem:
        return pc.impact_oscillator(frequency=w, **{**parameters, "force": force})

    # the non-impacting orbit, continued
    solve = pc.stroboscopic_solver(lambda force: pc.without_impacts(system_at(force)))

    def grazing(force: float, x: np.ndarray) -> float:
        return pc.smallest_gap(system_at(force), 0.0, x)

    F_graze = sigma * math.hypot(1.0 - w**2, 0.05 * w)  # free amplitude F/|k - mω² + icω| = σ
    branch = pc.continuation(
        solve, np.array([0.15, 0.17, 0.19]), np.array([0.4, 0.0]), grazing=grazing, tol=1e-10
    )
    found = [b for b in branch.bifurcations if b.kind == "grazing"]
    assert len(found) == 1
    assert abs(found[0].parameter / F_graze - 1.0) <= 1e-6


def test_bifurcation_figure_draws_branch_and_diagram(tmp_path) -> None:
    A_flip = pc.vibrating_table_flip_amplitude(frequency=_W, restitution=_E)

    def step(A: float, z: np.ndarray) -> np.ndarray:
        system = pc.vibrating_table_ball(
            amplitude=A, frequency=_W, restitution=_E, stick_velocity=1e-6
        )
        return pc.impact_map(system)(z)

    z0 = analytic_ball_orbit(0.9 * A_flip)
    diagram = pc.orbit_diagram(
        step,
        np.array([0.9, 0.95, 1.08]) * A_flip,
        z0,
        coordinate=lambda z: z[0] % _T,
        transient=60,
        keep=8,
    )
    # one impact phase per amplitude below the flip, two above it (the period-2 orbit)
    below = np.unique(np.round(diagram[1][diagram[0] < A_flip], 5))
    above = np.unique(np.round(diagram[1][diagram[0] == diagram[0].max()], 5))
    assert below.size == 2 and above.size == 2
    figure = pc.bifurcation_figure(diagram, xlabel="A [m]", ylabel="impact phase [s]")
    figure.savefig(tmp_path / "diagram.png")
    assert (tmp_path / "diagram.png").stat().st_size > 1000


def test_scene_stroboscopic_map_converges_to_the_oscillator_map() -> None:
    """The oscillator as a scene maps the period-1 orbit onto itself up to O(h).

    robots/impact_oscillator.toml is run by simulate (event-driven), the spring, damper and
    forcing held over each step.
    """
    import dataclasses

    from tests.conftest import ROBOTS
    from ucontrol.scene import Scene
    from ucontrol.scene_maps import scene_stroboscopic_map

    w = 2.4
    found = oscillator_fixed_point(w, np.array([-1.0, 0.1]))
    scene = Scene.from_toml(ROBOTS / "impact_oscillator.toml")
    assert np.max(np.abs(np.concatenate((scene.q0, scene.v0)) - found.z)) <= 1e-9
    forcing = pc.SinusoidalForcing(stiffness=1.0, damping=0.05, force=1.0, frequency=w)
    period = 2 * math.pi / w
    errors = []
    for steps in (500, 1000):
        settings = dataclasses.replace(scene.integrator, dt=period / steps)
        P = scene_stroboscopic_map(dataclasses.replace(scene, integrator=settings), forcing, period)
        errors.append(np.max(np.abs(P(found.z) - found.z)))
    assert errors[1] < 0.7 * errors[0]  # first order in h (zero-order hold)
    assert errors[1] < 1e-2


@pytest.mark.slow
def test_impact_oscillator_experiment_runs(tmp_path) -> None:
    from tests.conftest import load_experiment

    written = load_experiment("impact_oscillator").main(["--out", str(tmp_path), "--points", "2"])
    assert all(path.exists() for path in written)
    assert "period doubling" in (tmp_path / "impact_oscillators.md").read_text()
