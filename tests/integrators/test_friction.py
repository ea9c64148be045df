"""Moreau–Jean with Coulomb friction: the acceptance cases of issue 3, the backends, the errors.

The scenes come from ``experiments/friction_cases.py`` (the block on an incline or on flat
ground, Painlevé's rod, the column of beads), which also prints the figures of docs/friction.md.
"""

from __future__ import annotations

import dataclasses
import math
import subprocess
import sys
import warnings

import numpy as np
import pytest
from conftest import ROBOTS, ball_scene, load_experiment

from ucontrol.exceptions import (
    ContactSolveError,
    ContactSolveWarning,
    InvalidParameterError,
    NotFoundError,
    SimulationError,
    UnknownKeyError,
    URDFError,
)
from ucontrol.integrators import MoreauJean
from ucontrol.log import UNSOLVED
from ucontrol.model import example_robot_data_dir
from ucontrol.plant import StepOutcome
from ucontrol.scene import IntegratorSettings, Scene, load_scene
from ucontrol.simulate import simulate
from ucontrol.solvers import ProxsuiteCoulombSolver

_G = 9.81  # [m/s²]
_MU = 0.5
_ACCELERATION_TOLERANCE = 1e-9  # relative, issue 3
_STUCK = 1e-12  # [m/s], largest slope speed of a block that sticks


@pytest.fixture(scope="module")
def cases():  # type: ignore[no-untyped-def]
    return load_experiment("friction_cases")


@pytest.mark.parametrize("spatial", [False, True], ids=["planar", "spatial"])
@pytest.mark.parametrize("degrees", [15.0, 26.0, 35.0, 50.0])
def test_block_on_incline_sticks_iff_tan_alpha_below_mu(
    cases, spatial: bool, degrees: float
) -> None:
    alpha = math.radians(degrees)
    result = cases.incline_case(alpha, _MU, spatial=spatial, duration=0.5)
    assert result["max_residual"] <= 1e-10
    if math.tan(alpha) <= _MU:
        assert result["max_speed_if_stuck"] <= _STUCK
    else:
        assert result["expected"] == pytest.approx(_G * (math.sin(alpha) - _MU * math.cos(alpha)))
        assert result["relative_error"] <= _ACCELERATION_TOLERANCE, result


@pytest.mark.slow
@pytest.mark.parametrize("spatial", [False, True], ids=["planar", "spatial"])
def test_block_at_the_friction_angle_sticks_for_ever(cases, spatial: bool) -> None:
    """At tan α = μ (to round-off) friction at its bound holds the block."""
    result = cases.incline_case(math.atan(_MU), _MU, spatial=spatial, duration=2.0)
    assert result["max_speed_if_stuck"] <= 1e-11  # round-off creep only


@pytest.mark.slow
def test_sliding_block_stops_at_the_analytic_time_and_distance(cases) -> None:
    v0 = 1.0  # [m/s]
    t_star, d_star = v0 / (_MU * _G), v0**2 / (2.0 * _MU * _G)
    for dt in (1e-2, 1e-3, 1e-4):
        result = cases.stop_case(v0, _MU, dt)
        assert abs(result["t_error"]) <= dt, (dt, result)  # O(h): the step it stops in
        assert abs(result["d_error"]) <= v0 * dt, (dt, result)
        assert result["t_stop"] == pytest.approx(t_star, abs=dt)
        assert result["distance"] == pytest.approx(d_star, abs=v0 * dt)


def test_painleve_rod_has_a_tangential_impact(cases) -> None:
    """μ above critical: no force solves the acceleration level, a finite impulse does."""
    scene = cases.painleve(1.5)
    k, a_free = cases.acceleration_problem(scene)
    assert k < 0.0 and a_free < 0.0  # no lambda >= 0 with k lambda + a_free >= 0
    impulses = [cases.painleve_case(1.5, dt)["impulse"] for dt in (1e-3, 1e-4)]
    assert impulses[1] == pytest.approx(impulses[0], rel=0.03)  # independent of h: an impulse
    assert impulses[1] > 300 * _G * 1e-4  # hundreds of times m g h
    first = cases.painleve_case(1.5, 1e-3)
    assert abs(first["sliding_speed_after"]) < 1e-3  # the sliding stops at once
    result = simulate(scene, duration=1.0)
    assert np.all(np.isfinite(result.log.q)) and np.all(np.isfinite(result.log.v))
    assert np.max(np.abs(result.log.v)) < 10.0  # no blow-up
    assert result.summary["max_complementarity_residual"] <= 1e-10
    below = cases.painleve_case(1.0, 1e-3)  # μ below critical: a force, O(h)
    assert below["impulse_over_mgh"] < 3.0 and below["sliding_speed_after"] > 0.9


@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_column_of_beads(cases, friction: float) -> None:
    """No interpenetration beyond the scheme's h × closing speed, no energy at impacts."""
    result = cases.beads_case(friction, 3.0 if friction == 0.0 else 1.5)
    assert result["max_penetration"] <= result["h_times_closing_speed"]
    assert result["steps_with_several_impacts"] > 10  # simultaneous impacts happen
    assert result["energy_increase_at_impacts"] == 0.0
    assert result["max_lateral_position"] <= 1e-9


def test_simultaneous_frictional_impacts_on_a_tilted_table() -> None:
    """Four feet with e = 0.5 and μ = 0.5 hitting in a few steps: energy never rises."""
    scene = load_scene(ROBOTS / "table_drop.toml")
    tilt = np.array([0.0, np.sin(0.05), 0.0, np.cos(0.05)])  # 0.1 rad about y
    q0 = np.concatenate(([0.0, 0.0, 0.45], tilt))
    contacts = tuple(dataclasses.replace(c, friction=0.5) for c in scene.contacts)
    v0 = np.array([0.5, 0.2, 0.0, 0.0, 0.0, 1.0])  # sliding and spinning as it lands
    result = simulate(dataclasses.replace(scene, contacts=contacts, q0=q0, v0=v0), duration=1.0)
    summary = result.summary
    assert summary["energy_increase_at_impacts"] <= 1e-9 * summary["initial_energy"]
    assert summary["n_impacts"] >= 4
    assert summary["max_complementarity_residual"] <= 1e-8
    friction = np.linalg.norm(result.log.friction_impulse, axis=2)
    assert np.all(friction <= 0.5 * result.log.impulse + 1e-12)


def test_scene_without_friction_builds_no_friction_machinery() -> None:
    code = (
        "import sys\n"
        "from ucontrol.scene import load_scene\n"
        "from ucontrol.simulate import simulate\n"
        f"scene = load_scene({str(ROBOTS / 'ball.toml')!r})\n"
        "integrator = scene.build_integrator()\n"
        "result = simulate(scene, duration=0.5)\n"
        "assert integrator.friction_solver is None\n"
        "assert 'friction_impulse' not in result.log.fields\n"
        "assert 'ucontrol.solvers.proxsuite_coulomb' not in sys.modules\n"
        "assert 'qpsolvers' not in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_friction_solve_results_are_logged_and_summarised(cases) -> None:
    result = simulate(cases.incline(math.radians(35.0), _MU), duration=0.2)
    log, summary = result.log, result.summary
    assert np.all(log.solver_status[:-1] == 1)  # solved at every step
    assert np.all(log.complementarity_residual[:-1] <= 2e-16)  # measured 2.1e-17 m/s
    assert log.solver_outer_iterations.max() >= 1
    assert log.friction_impulse.shape == (len(log), 2, 3)
    assert summary["contact_solves"] == summary["steps"]
    assert summary["n_unsolved_contact_solves"] == 0
    # The summary's timing figures are those of the log's solves.
    times = log.solver_time[:-1]
    assert summary["mean_contact_solve_us"] == pytest.approx(1e6 * times.mean(), rel=1e-12)
    assert summary["contact_solve_time_s"] == pytest.approx(times.sum(), rel=1e-12)
    assert summary["max_complementarity_residual"] <= 1e-10


def test_unsolved_step_raises_or_warns_with_its_residual(cases) -> None:
    scene = cases.incline(math.radians(35.0), _MU)
    crippled = ProxsuiteCoulombSolver(max_iter=1, polish=False)  # one unpolished Tresca QP

    def step(on_unsolved: str) -> StepOutcome:
        integrator = MoreauJean(
            scene.robot,
            scene.constraints,
            dt=1e-3,
            friction_solver=crippled,
            on_unsolved=on_unsolved,
        )
        return integrator.step(integrator.evaluate(scene.q0, scene.v0), np.zeros(3))

    with pytest.raises(ContactSolveError, match="tolerance 1e-08 m/s") as info:
        step("raise")
    assert info.value.residual > info.value.tolerance == 1e-8
    with pytest.warns(ContactSolveWarning, match="residual .* above the tolerance") as record:
        outcome = step("warn")
    assert outcome.solution is not None
    assert record[0].message.residual == outcome.solution.residual > 1e-8  # type: ignore[union-attr]
    # From a scene: no solve reaches a residual of 1e-30 m/s.
    settings = IntegratorSettings(friction_tolerance=1e-30, friction_max_iter=2)
    warned = dataclasses.replace(
        scene, integrator=dataclasses.replace(settings, on_unsolved="warn")
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ContactSolveWarning)
        result = simulate(warned, duration=0.02)
    unsolved = int(np.sum(result.log.solver_status == UNSOLVED))
    # Exactly the steps above 1e-30 m/s are unsolved (a residual of exactly 0 is solved: the
    # compiled Newton steps, kept down to round-off, reach it on some steps).
    assert unsolved > 0
    assert unsolved == int(np.sum(result.log.complementarity_residual > 1e-30))
    assert result.summary["n_unsolved_contact_solves"] == unsolved
    raising = dataclasses.replace(scene, integrator=settings)
    with pytest.raises(SimulationError, match="proxsuite-tresca failed"):
        simulate(raising, duration=0.02)


@pytest.mark.parametrize("name", ["pinocchio-admm", "pinocchio-pgs"])
def test_pinocchio_solvers_as_contact_solvers(cases, name: str) -> None:
    alpha = math.radians(35.0)
    scene = cases.incline(alpha, _MU)
    scene = dataclasses.replace(scene, integrator=IntegratorSettings(contact_solver=name))
    result = simulate(scene, duration=0.2)
    acceleration = np.diff(cases.slope_velocity(result, alpha)) / 1e-3
    expected = _G * (math.sin(alpha) - _MU * math.cos(alpha))
    assert np.max(np.abs(acceleration - expected)) <= 1e-6 * expected


def test_qpsolvers_backend_runs_a_frictionless_scene() -> None:
    reference = simulate(ball_scene(0.9), duration=1.0)
    scene = ball_scene(0.9, integrator=IntegratorSettings(contact_solver="qpsolvers:proxqp"))
    result = simulate(scene, duration=1.0)
    assert np.allclose(result.log.q, reference.log.q, atol=1e-12)


def test_scene_settings_errors(cases) -> None:
    friction = cases.incline(0.3, _MU)
    with pytest.raises(InvalidParameterError, match="'event_driven' for contacts with friction"):
        dataclasses.replace(
            friction, integrator=IntegratorSettings(name="compliant")
        ).build_integrator()
    with pytest.raises(InvalidParameterError, match="qpsolvers backends solve the frictionless"):
        dataclasses.replace(
            friction, integrator=IntegratorSettings(contact_solver="qpsolvers:proxqp")
        ).build_integrator()
    with pytest.raises(NotFoundError, match="unknown contact solver 'gurobi'"):
        IntegratorSettings(contact_solver="gurobi")
    with pytest.raises(NotFoundError, match="unknown qpsolvers solver 'nope'"):
        ball_scene(
            0.9, integrator=IntegratorSettings(contact_solver="qpsolvers:nope")
        ).build_integrator()
    with pytest.raises(InvalidParameterError, match="`on_unsolved` must be one of"):
        IntegratorSettings(on_unsolved="ignore")
    with pytest.raises(InvalidParameterError, match="`on_unsolved` must be one of"):
        MoreauJean(friction.robot, friction.constraints, dt=1e-3, on_unsolved="ignore")
    with pytest.raises(InvalidParameterError, match="`friction_tolerance` must be > 0"):
        IntegratorSettings(friction_tolerance=0.0)


def test_scene_file_keys() -> None:
    scene = load_scene(ROBOTS / "beads.toml")
    assert len(scene.sphere_contacts) == 9 and scene.constraints.size == 10
    assert scene.planar_axis is not None and scene.planar_axis.tolist() == [0.0, 1.0, 0.0]
    table = {
        "robot": {"urdf": "beads.urdf"},
        "sphere_contacts": [{"frame": "bead1", "other_frame": "bead0", "spin": 1.0}],
    }
    with pytest.raises(UnknownKeyError, match=r"'spin' in \[\[sphere_contacts\]\]"):
        Scene.from_dict(table, base_dir=ROBOTS)


@pytest.mark.parametrize(
    "name",
    [
        "block_incline.toml",
        "block_incline_spatial.toml",
        "painleve_rod.toml",
        "beads.toml",
        "panda_table_friction.toml",
    ],
)
def test_shipped_friction_scenes_run(name: str) -> None:
    if name.startswith("panda"):
        try:
            example_robot_data_dir()
        except URDFError:
            pytest.skip("example-robot-data is not installed (extra `robots`)")
    result = simulate(load_scene(ROBOTS / name), duration=0.3)
    summary = result.summary
    assert summary["n_unsolved_contact_solves"] == 0
    assert np.all(np.isfinite(result.log.q))
    # Coulomb's law to round-off at every step (measured <= 2.0e-14 m/s, the Painleve rod's
    # 148 impacts), penetration within the closure offset (measured 1.0e-10 m) and no
    # energy gained at an impact (measured 0 J).
    assert summary["max_complementarity_residual"] <= 2e-13
    assert summary["max_penetration"] <= 1e-9
    assert summary["energy_increase_at_impacts"] <= 0.0


@pytest.mark.slow
def test_beads_event_driven_and_moreau_jean_agree() -> None:
    """Sphere–sphere contacts in both integrators: Moreau–Jean tends to event-driven as h → 0."""
    scene = load_scene(ROBOTS / "beads.toml")
    exact = simulate(
        dataclasses.replace(scene, integrator=IntegratorSettings(name="event_driven")),
        duration=0.6,
    )
    errors = []
    for dt in (1e-3, 1e-4):
        stride = round(1e-3 / dt)
        heights = simulate(scene, duration=0.6, dt=dt).log.q[::stride, 1::3]
        errors.append(np.max(np.abs(heights - exact.log.q[:, 1::3])))
    assert errors[1] < errors[0] / 5.0  # order about one
    assert errors[1] < 5e-3  # [m]
