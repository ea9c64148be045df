"""The a-priori weak-stability check (`ucontrol check`) against closed forms and runs.

References: the Hermite approach cubic solved by hand for the first impact; the bouncing ball
(Newton's law under gravity) for the accumulation-time bound; and, for the acceptance of
issue 29, the quantities measured over ten cycles of the two-link one-constraint task for
e = 0.5, 0.7, 0.9, which must stay within the bounds computed before the run.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from ucontrol.analysis.stability_check import (
    EXIT_CONDITION_FAILS,
    _flight_time,
    _tail,
    check_scene,
    compare_with_run,
)
from ucontrol.cli import main
from ucontrol.exceptions import InvalidParameterError
from ucontrol.scene import Scene, load_scene
from ucontrol.simulate import simulate

SCENE = "two_link_one_constraint"
#: Ten cycles of period 10 s: the last approach starts at 94.2 s, its takeoff ends at 100.4 s.
TEN_CYCLES = 101.0


def _with_restitution(scene: Scene, e: float) -> Scene:
    contact = dataclasses.replace(scene.contacts[0], restitution=e, name=scene.contacts[0].name)
    return dataclasses.replace(scene, contacts=(contact,))


def test_first_impact_is_where_the_approach_cubic_crosses_the_surface() -> None:
    """t0 and v0 against the cubic from the circle's gap at tau0 to -d_min at rest."""
    check = check_scene(load_scene(SCENE)).contacts[0]
    # circle of centre (0.65, 0), radius 0.1, period 10 s, from angle 0: gap y = 0.1 sin(ωt)
    omega, tau0, T, d = 2 * math.pi / 10.0, 4.2, 0.8, 0.01
    p0, v0 = 0.1 * math.sin(omega * tau0), 0.1 * omega * math.cos(omega * tau0)  # [m], [m/s]
    a2 = (3 * (-d - p0) - 2 * v0 * T) / T**2
    a3 = (2 * (p0 + d) + v0 * T) / T**3
    roots = np.roots([a3, a2, v0, p0])
    tau = min(r.real for r in roots if abs(r.imag) < 1e-12 and 0.0 < r.real < T)
    assert check.tau0 == pytest.approx(tau0)
    assert check.depth == pytest.approx(d)
    # sampled at 20 kHz: t0 is the first sample at or past the crossing
    assert check.first_impact - (tau0 + tau) == pytest.approx(0.0, abs=5.1e-5)
    velocity = v0 + 2 * a2 * tau + 3 * a3 * tau**2
    assert check.approach_velocity == pytest.approx(velocity, rel=1e-3)


@pytest.mark.slow
def test_impulse_on_a_held_contact_is_the_one_the_plant_applies() -> None:
    """Two constraints: at the wall's first impact the ground (held) takes the predicted impulse.

    The plant's ground impulse over that step is the predicted impulse plus lambda_d h.
    """
    scene = load_scene("two_link_two_constraints")
    wall = check_scene(scene).contacts[1]
    assert wall.contact == "end_effector/wall"
    assert [c.name for c in wall.conditions if c.name == "held_contacts_stay_closed"]
    log = simulate(scene, duration=wall.first_impact + 0.01).log
    ground, w = log.constraint_index("end_effector/ground"), log.constraint_index(wall.contact)
    row = int(np.flatnonzero(log.impulse[:, w] > 0.0)[0])
    h = float(log.t[row + 1] - log.t[row])  # [s]
    lambda_d = float(log.lambda_d[row, 0])  # [N]
    measured = float(log.impulse[row, ground]) - lambda_d * h  # [N s]
    assert measured == pytest.approx(wall.held_impulses[0], rel=0.05)


def test_accumulation_bound_of_an_undamped_ball_is_the_bouncing_ball_time() -> None:
    """Flights 2u/g and rebounds e u: t_inf - t0 = 2 u / (g (1 - e)) (c -> 0)."""
    u, g, e = 0.3, 9.81, 0.6
    assert _flight_time(u, g, 1e-9) == pytest.approx(2 * u / g, rel=1e-6)
    assert _tail(u, g, 1e-9, e) == pytest.approx(2 * u / (g * (1 - e)), rel=1e-6)
    # damping shortens the rise more than it lengthens the descent, never below sqrt(2H/g)
    assert _flight_time(u, g, 5.0) < 2 * u / g


@pytest.mark.slow
@pytest.mark.parametrize("e", [0.5, 0.7, 0.9])
def test_computed_bounds_hold_over_ten_cycles(e: float) -> None:
    """Issue 29 acceptance: the bounds computed before the run hold on every measured cycle."""
    scene = _with_restitution(load_scene(SCENE), e)
    check = check_scene(scene)
    assert check.holds, check.report()
    bounds = check.contacts[0]
    log = simulate(scene, duration=TEN_CYCLES).log
    measured = compare_with_run(check, log)["measured"][0]["cycles"]
    assert len(measured) == 10
    for cycle in measured:
        assert cycle["accumulation_time"] is not None  # every cycle settled
        assert cycle["impact_jumps"] <= bounds.jump_bound, cycle
        assert cycle["accumulation_time"] <= bounds.accumulation_time_bound, cycle
        assert cycle["min_constrained_force"] > 0.0, cycle
        assert cycle["jump_bound_holds"] and cycle["accumulation_bound_holds"]
    # once tracking has converged (V(tau0) ~ 1e-10 J) the run lands at the computed velocity
    # and its first jump of V is the computed one, up to the step's discretisation
    settled = measured[-1]
    assert settled["first_impact_velocity"] == pytest.approx(bounds.approach_velocity, rel=5e-3)
    assert settled["impact_jumps"] == pytest.approx(bounds.jump_bound, rel=0.1)


@pytest.mark.slow
def test_broken_gains_are_reported_before_the_run(tmp_path: Path, capsys) -> None:
    """gamma1 = 0.5: the pull towards the surface vanishes; the run does not settle."""
    code = main(["check", SCENE, "--set", "controller.gamma1=0.5"])
    assert code == EXIT_CONDITION_FAILS
    err = capsys.readouterr().err
    assert "condition finite_accumulation fails" in err and "gamma1 = 0.5" in err
    scene = load_scene(SCENE)
    broken = dataclasses.replace(scene, controller={**scene.controller, "gamma1": 0.5})
    failures = {c.name for c in check_scene(broken).failures}
    assert {"finite_accumulation", "accumulation_before_takeoff"} <= failures
    # the run confirms it: the first cycle never settles before its takeoff
    report = simulate(broken, duration=14.0).log
    from ucontrol.analysis.weak_stability import weak_stability

    assert not weak_stability(report).cycles[0].complete


@pytest.mark.slow
def test_cli_check_writes_the_bounds_beside_a_run(tmp_path: Path, capsys) -> None:
    out = tmp_path / "run"
    assert main(["run", SCENE, "--out", str(out), "--duration", "16", "--no-progress"]) == 0
    assert main(["check", SCENE, "--run", str(out)]) == 0
    assert "finite_accumulation: holds" in capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    cycles = summary["stability_check"]["measured"][0]["cycles"]
    assert [c["accumulation_bound_holds"] for c in cycles] == [True, True]
    assert "accumulation_time" in summary["weak_stability"]["cycles"][0]  # every run has them


def test_scene_without_a_brogliato_controller_is_refused(capsys) -> None:
    with pytest.raises(InvalidParameterError, match="controller"):
        check_scene(load_scene("ball"))
    assert main(["check", "ball"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ucontrol: error:") and len(err.strip().splitlines()) == 1


def test_flexible_joints_are_refused() -> None:
    with pytest.raises(InvalidParameterError, match="flexible"):
        check_scene(load_scene("two_link_flexible_one_constraint"))


@pytest.mark.parametrize("value", [-1.0, math.nan])
def test_bad_V1_tau0_is_refused(value: float, capsys) -> None:
    with pytest.raises(InvalidParameterError, match="V1_tau0"):
        check_scene(load_scene(SCENE), V1_tau0=value)
    assert main(["check", SCENE, "--V1-tau0", str(value)]) == 2


def test_run_of_another_controller_is_refused(tmp_path: Path, capsys) -> None:
    check = check_scene(load_scene(SCENE))
    log = simulate(load_scene("ball"), duration=0.01).log
    with pytest.raises(InvalidParameterError, match="Brogliato"):
        compare_with_run(check, log)
    assert main(["check", SCENE, "--run", str(tmp_path / "missing")]) == 2
