"""The closed loop: controller protocol, zero-order hold, failures mid-run, several scenes."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import ROBOTS, ball_scene

from ucontrol import cli
from ucontrol.analysis import BouncingBall
from ucontrol.contact import PointContact
from ucontrol.control import ContactState, JointPD
from ucontrol.exceptions import ShapeError, SimulationError
from ucontrol.log import Log
from ucontrol.scene import Scene, load_scene
from ucontrol.simulate import simulate


class _Recorder:
    """Pushes the ball up with a constant force and remembers when it was called."""

    def __init__(self, force: float) -> None:
        self.force = force
        self.times: list[float] = []
        self.contacts: list[ContactState] = []

    def __call__(self, t, q, v, contacts):
        self.times.append(t)
        self.contacts.append(contacts)
        return np.array([self.force])


def test_zero_order_hold_calls_the_controller_once_per_period() -> None:
    controller = _Recorder(0.0)
    simulate(ball_scene(0.9), controller, duration=0.1, dt=1e-3, control_period=1e-2)
    np.testing.assert_allclose(controller.times, np.arange(10) * 1e-2, atol=1e-12)


def test_controller_torque_enters_the_dynamics() -> None:
    # A constant upward force of m g / 2 halves the effective gravity: y = y0 - g t² / 4.
    controller = _Recorder(0.5 * 9.81)
    log = simulate(ball_scene(0.9), controller, duration=0.3, dt=1e-3).log
    np.testing.assert_allclose(log.q[:, 0], 1.1 - 9.81 * log.t**2 / 4.0, atol=1e-12)
    np.testing.assert_allclose(log.u[:, 0], 0.5 * 9.81)


def test_contact_state_given_to_the_controller() -> None:
    controller = _Recorder(0.0)
    simulate(ball_scene(0.0), controller, duration=0.6, dt=1e-3)
    resting = controller.contacts[-1]
    assert resting.names == ["ball/ground"]
    assert resting.active[0]
    assert resting.force[0] == pytest.approx(9.81, rel=1e-12)  # impulse / dt of a resting ball
    assert abs(resting.gap[0]) < 1e-2


def test_failure_mid_run_keeps_the_log(tmp_path: Path) -> None:
    def failing(t, q, v, contacts):
        if t >= 0.5:
            raise ShapeError("u", (1,), (2,))
        return np.zeros(1)

    with pytest.raises(SimulationError) as info:
        simulate(ball_scene(0.9), failing, duration=1.0, dt=1e-3, out=tmp_path)
    error = info.value
    assert error.time == pytest.approx(0.5)
    assert "t = 0.5" in str(error) and "`u`" in str(error) and "log.npz" in str(error)
    saved = Log.load(tmp_path / "log.npz")
    assert len(saved) == len(error.log) == 501
    assert saved.t[-1] == pytest.approx(0.5)
    np.testing.assert_array_equal(saved.q, error.log.q)
    flight = saved.t < 0.45  # before the first impact the θ = 1/2 scheme is exact
    reference = BouncingBall(height=1.0, restitution=0.9)
    height = reference.state(saved.t[flight])[0]
    np.testing.assert_allclose(saved.q[flight, 0] - 0.1, height, atol=1e-12)


def test_interrupted_run_keeps_the_log(tmp_path: Path) -> None:
    def interrupted(t, q, v, contacts):
        if t >= 0.3:
            raise KeyboardInterrupt  # the user's Ctrl-C, seen where Python checks signals
        return np.zeros(1)

    with pytest.raises(KeyboardInterrupt):
        simulate(ball_scene(0.9), interrupted, duration=1.0, dt=1e-3, out=tmp_path)
    saved = Log.load(tmp_path / "log.npz")
    assert len(saved) == 301 and saved.t[-1] == pytest.approx(0.3)
    reference = BouncingBall(height=1.0, restitution=0.9)
    np.testing.assert_allclose(saved.q[:, 0] - 0.1, reference.state(saved.t)[0], atol=1e-12)


def test_cli_reports_an_interrupt_in_one_line(monkeypatch, capsys) -> None:
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    # the command imports simulate when it runs (its signals are handled first)
    monkeypatch.setattr(sys.modules["ucontrol.simulate"], "simulate", interrupted)
    assert cli.main(["run", str(ROBOTS / "ball.toml"), "--out", "unused"]) == 130
    assert capsys.readouterr().err.strip() == (
        "ucontrol: interrupted by SIGINT; nothing was written"
    )


def test_non_finite_controller_output_stops_the_run_with_its_time() -> None:
    def exploding(t, q, v, contacts):
        return np.array([np.nan if t >= 0.2 else 0.0])

    with pytest.raises(SimulationError, match=r"t = 0.2 s.*finite") as info:
        simulate(ball_scene(0.9), exploding, duration=1.0, dt=1e-3)
    assert np.all(np.isfinite(info.value.log.q))


def test_wrong_controller_output_size_is_named() -> None:
    with pytest.raises(SimulationError, match=r"`controller output u` must have shape \(1,\)"):
        simulate(ball_scene(0.9), lambda t, q, v, c: np.zeros(3), duration=0.1)


def test_joint_pd_regulates_the_arm_against_gravity(two_link_scene: Scene) -> None:
    q_ref = np.array([1.5, -1.4])  # end effector at (0.53, 0.55), away from every constraint
    controller = JointPD(two_link_scene.robot, q_ref=q_ref, kp=200.0, kd=30.0)
    result = simulate(two_link_scene, controller, duration=4.0, dt=1e-3)
    np.testing.assert_allclose(result.log.q[-1], q_ref, atol=1e-4)
    assert result.summary["n_impacts"] == 0


def test_two_link_drop_is_physical(two_link_scene: Scene) -> None:
    result = simulate(two_link_scene, duration=3.0, dt=1e-3)
    summary = result.summary
    assert summary["n_impacts"] > 0
    assert summary["energy_increase_at_impacts"] <= 1e-9
    assert summary["max_penetration"] < 1e-3  # O(h · impact speed)
    assert summary["max_complementarity_residual"] < 1e-8
    energy = result.log.energy
    assert energy[-1] < energy[0]  # impacts with e < 1 and stops with e = 0 dissipate
    q = result.log.q
    assert np.all(q[:, 0] > -1e-3) and np.all(q[:, 1] < 1e-3)  # stops hold


def test_free_flyer_ball_follows_the_analytic_heights() -> None:
    scene = load_scene(ROBOTS / "free_ball.toml")
    assert (scene.robot.nq, scene.robot.nv, scene.robot.nu) == (7, 6, 0)
    reference = BouncingBall(height=1.0, restitution=0.9)
    flight, whole = [], []
    for dt in (1e-3, 1e-4):
        log = simulate(scene, duration=2.5, dt=dt).log
        error = np.abs(log.q[:, 2] - 0.1 - reference.state(log.t)[0])
        flight.append(np.max(error[log.t < 0.44]))  # before the first impact (t = 0.4515 s)
        whole.append(np.max(error))
        np.testing.assert_allclose(np.linalg.norm(log.q[:, 3:], axis=1), 1.0, atol=1e-12)
    # The spin (2 and 5 rad/s) leaks into the height at O(h): first order in flight (measured
    # ratio 9.9, 1.4e-4 then 1.5e-5 m); through five impacts the largest error, at an impact,
    # depends on where the impact falls between samples (9.6e-3 and 1.7e-3 m).
    assert flight[0] / flight[1] >= 9.0
    assert whole[1] < 2e-3


def test_more_contacts_than_degrees_of_freedom() -> None:
    # Three contacts on the one-dof ball: D = J M⁻¹ Jᵀ has rank 1. The velocity is unique.
    scene = ball_scene(0.5)
    contact = scene.contacts[0]
    twins = tuple(dataclasses.replace(contact, name=f"ball/ground/{i}") for i in range(3))
    redundant = dataclasses.replace(scene, contacts=twins)
    single = simulate(scene, duration=2.0, dt=1e-3).log
    triple = simulate(redundant, duration=2.0, dt=1e-3).log
    np.testing.assert_allclose(triple.q, single.q, atol=1e-9)
    np.testing.assert_allclose(triple.impulse.sum(axis=1), single.impulse[:, 0], atol=1e-9)
    assert np.max(triple.complementarity_residual) < 1e-8


def test_redundant_corner_contacts_on_the_arm(two_link_scene: Scene) -> None:
    # The end effector pushed into the corner ground/wall while both elbow stops are near: the
    # constraint Jacobian has more rows than the arm has joints.
    corner = dataclasses.replace(
        two_link_scene,
        contacts=(
            *two_link_scene.contacts,
            PointContact(
                frame="end_effector",
                surface=two_link_scene.contacts[0].surface,
                restitution=0.0,
                name="end_effector/ground/twin",
            ),
        ),
    )
    controller = JointPD(corner.robot, q_ref=np.array([0.3, -0.9]), kp=400.0, kd=5.0)
    result = simulate(corner, controller, duration=2.0, dt=1e-3)
    assert result.summary["max_complementarity_residual"] < 1e-8
    assert result.summary["max_penetration"] < 1e-3
    assert np.all(np.isfinite(result.log.v))


def test_folded_arm_hitting_ground_and_elbow_stop_gains_no_energy(two_link_scene: Scene) -> None:
    # Thrown into the folded configuration, the end effector reaches the ground at the shoulder
    # while the elbow hits its stop: the two constraint rows are almost dependent and have
    # unequal restitutions (0.7 and 0). Newton's generalized law then asks for impulses that
    # add energy; the step must fall back to the plastic law instead. The tip starts 1 µm
    # above the ground (q2 = -1.8 + 3.2e-6): exactly on it, it would be held from the first
    # step (contacts closed at the start) and would not impact.
    scene = dataclasses.replace(
        two_link_scene, q0=np.array([0.9, -1.8 + 3.2e-6]), v0=np.array([5.0, -10.0])
    )
    result = simulate(scene, duration=1.0, dt=1e-3)
    assert result.summary["n_plastic_steps"] >= 1
    assert np.max(np.diff(result.log.energy)) <= 1e-9
    assert result.summary["max_complementarity_residual"] < 1e-8


@pytest.mark.parametrize(
    "first", ["", "import ucontrol.simulate\n", "from ucontrol.simulate import SimulationResult\n"]
)
def test_from_ucontrol_import_simulate_runs_a_simulation(first: str) -> None:
    """`ucontrol.simulate` is both the module and the function's name: either runs a run."""
    code = (
        first + "from ucontrol import load_scene, simulate\n"
        "result = simulate(load_scene('ball'), duration=0.01)\n"
        "print(result.summary['steps'])\n"
    )
    completed = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    assert completed.stdout.strip() == "10"
