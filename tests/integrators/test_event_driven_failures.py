r"""The event-driven integrator's failures, raised where the physics puts them.

The ball of robots/ball.toml (1 kg, radius 0.1 m, dropped from a gap of 1 m, e = 0.9) first
lands at :math:`t_1 = \sqrt{2 h / g} = 0.4515` s, then after flights of :math:`2 e^k t_1`:
:math:`t_2 = t_1 (1 + 2e)`, :math:`t_3 = t_1 (1 + 2e + 2e^2)`.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from ucontrol.exceptions import IntegrationError, SimulationError, SolverError
from ucontrol.integrators import event_driven
from ucontrol.integrators.event_driven import EventDriven
from ucontrol.scene import Scene, load_scene
from ucontrol.simulate import simulate
from ucontrol.solvers.contact_solution import ContactSolution
from ucontrol.solvers.proxsuite_lcp import ProxsuiteLCPSolver

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
G, HEIGHT, E = 9.81, 1.0, 0.9  # [m/s²], [m], restitution
T1 = math.sqrt(2.0 * HEIGHT / G)  # [s], first landing


def _ball() -> Scene:
    return load_scene(ROBOTS / "ball.toml")


def _event_driven(scene: Scene, **settings: object) -> EventDriven:
    integrator = scene.build_integrator()
    return EventDriven(integrator.robot, integrator.constraints, **settings)  # type: ignore[arg-type]


def test_more_events_than_allowed_in_a_step_raise_at_the_landing_that_exceeds_them() -> None:
    scene = _ball()
    integrator = _event_driven(scene, dt=2.0, max_events=2, zeno_velocity=1e-8)
    with pytest.raises(IntegrationError, match="more than 2 events in one step of 2 s") as raised:
        integrator.step(integrator.evaluate(scene.q0, scene.v0), np.zeros(1))
    t3 = T1 * (1.0 + 2.0 * E + 2.0 * E**2)  # [s], the third landing
    # Measured: 5.8e-15 s from t3 (event location at rtol 1e-10, atol 1e-12).
    assert raised.value.time == pytest.approx(t3, abs=5e-14)
    assert raised.value.integrator == "event_driven"
    # Three landings fit in the step allowed three events: no error, the ball flies on.
    integrator = _event_driven(scene, dt=2.0, max_events=3, zeno_velocity=1e-8)
    outcome = integrator.step(integrator.evaluate(scene.q0, scene.v0), np.zeros(1))
    assert outcome.events == 3 and outcome.v[0] > 0.0


def test_a_force_that_overflows_every_step_raises_an_integration_error() -> None:
    # 1e308 N on 1 kg: any Runge–Kutta stage overflows the doubles, every step is rejected
    # until the step size is below the spacing of the numbers.
    scene = _ball()
    integrator = _event_driven(scene, dt=1e-3)
    with np.errstate(all="ignore"), pytest.raises(IntegrationError) as raised:
        integrator.step(integrator.evaluate(scene.q0, scene.v0), np.array([1e308]))
    assert raised.value.time == 0.0
    assert "step size" in raised.value.reason


def test_an_unsolved_impact_stops_the_run_at_the_landing(monkeypatch: pytest.MonkeyPatch) -> None:
    # A contact solver that reports every solve unsolved: nothing is solved in the flight,
    # the first solve is the landing's impact, in the step that holds t1.
    solve = ProxsuiteLCPSolver.solve

    def unsolved(self: ProxsuiteLCPSolver, D: np.ndarray, b: np.ndarray) -> ContactSolution:
        return solve(self, D, b)._replace(status="max_iterations_reached", residual=0.5)

    monkeypatch.setattr(ProxsuiteLCPSolver, "solve", unsolved)
    scene = Scene.from_dict(  # the ball, run by the event-driven integrator
        {
            "name": "ball",
            "duration": 1.0,
            "robot": {"urdf": "ball.urdf", "q0": [1.1], "v0": [0.0]},
            "surfaces": {"ground": {"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 1]}},
            "contacts": [{"frame": "ball", "surface": "ground", "radius": 0.1, "restitution": E}],
            "integrator": {"name": "event_driven", "dt": 1e-3},
        },
        base_dir=ROBOTS,
    )
    with pytest.raises(SimulationError) as raised:
        simulate(scene, duration=1.0)
    error = raised.value
    assert error.step == math.floor(T1 / 1e-3)  # the step [451 ms, 452 ms]
    cause = error.__cause__
    assert isinstance(cause, SolverError)
    assert (cause.solver, cause.status, cause.residual) == (
        "proxsuite",
        "max_iterations_reached",
        0.5,
    )
    # Up to the landing the log is the free fall (measured error 2.6e-15 m).
    t = error.log.t
    np.testing.assert_allclose(error.log.q[:, 0], 1.1 - 0.5 * G * t**2, atol=2.5e-14)


def test_landings_that_accumulate_below_the_time_resolution_raise_at_the_accumulation_point(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # With a Zeno velocity of 1e-12 m/s nothing stops the bounces before their flights
    # (2 e^k t1) are shorter than the time resolution, here raised from 1e-14 s to 1e-6 s so
    # that the stall comes after ~100 landings: 51 events in a row closer than 1 us stop the
    # step just before the accumulation point t_inf = t1 (1 + 2e / (1 - e)) = 8.579 s.
    monkeypatch.setattr(event_driven, "_STALL_TIME", 1e-6)
    scene = _ball()
    integrator = _event_driven(scene, dt=10.0, zeno_velocity=1e-12)
    with pytest.raises(IntegrationError, match="51 events without the time advancing") as raised:
        integrator.step(integrator.evaluate(scene.q0, scene.v0), np.zeros(1))
    t_inf = T1 * (1.0 + 2.0 * E / (1.0 - E))  # [s]
    # Measured: 4.2e-8 s before t_inf (the flights left sum to less than 1e-5 s).
    assert 0.0 < t_inf - raised.value.time < 5e-7
