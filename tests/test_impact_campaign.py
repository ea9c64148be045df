"""experiments/impact_campaign.py: its table, and what the controllers of its runs see."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from conftest import load_experiment

from ucontrol.analysis.impact_metrics import WINDOW, target_velocities
from ucontrol.campaign import load
from ucontrol.control.controller import ContactState
from ucontrol.model import RobotModel
from ucontrol.scene import Scene
from ucontrol.sensors import Sensors
from ucontrol.simulate import simulate

Z = 1.959963984540054  # the 0.975 quantile of the standard normal


def _wilson(k: int, n: int) -> tuple[float, float]:
    """Wilson's score interval, solved from |p_hat - p| = z sqrt(p (1 - p) / n) for p."""
    p_hat = k / n
    # (1 + z²/n) p² - (2 p_hat + z²/n) p + p_hat² = 0
    a, b, c = 1 + Z**2 / n, -(2 * p_hat + Z**2 / n), p_hat**2
    root = math.sqrt(b * b - 4 * a * c)
    return (-b - root) / (2 * a), (-b + root) / (2 * a)


def test_wilson_reference_formula() -> None:
    # 40 successes out of 40 give [n / (n + z²), 1] (docs/campaigns.md: [0.912, 1])
    low, high = _wilson(40, 40)
    assert low == pytest.approx(40 / (40 + Z**2)) and high == pytest.approx(1.0)
    assert round(low, 3) == 0.912


@pytest.mark.slow
def test_campaign_command_writes_the_table(tmp_path: Path) -> None:
    campaign = load_experiment("impact_campaign")
    laws = ["reference spreading", "impedance"]
    argv = ["--runs", "2", "--tasks", "panda", "--laws", *laws, "--workers", "1"]
    text = campaign.main([*argv, "--out", str(tmp_path)])
    lines = text.splitlines()
    assert len(lines) == 2 + len(laws)  # header, separator, one row per law
    header = [cell.strip() for cell in lines[0].strip("|").split("|")]
    assert header[:3] == ["task", "law", "runs"] and header[-2:][0] == "success"
    for line, law in zip(lines[2:], laws, strict=True):
        cells = [cell.strip() for cell in line.strip("|").split("|")]
        assert len(cells) == len(header) and cells[:3] == ["panda", law, "2"]
        frame = load(tmp_path / f"panda_{law.replace(' ', '_')}")
        assert len(frame) == 2 and set(frame["status"]) == {"ok"}
        # success is the written definition, from the metric columns
        expected = (
            (frame["impacts"] >= 1)
            & frame["contact_held"].astype(bool)
            & (frame["settled_error"] < campaign.SETTLED_ERROR)
        )
        assert frame["success"].astype(bool).tolist() == expected.tolist()
        k = int(frame["success"].sum())
        assert cells[-2].startswith(f"{k}/2 = ")
        low, high = (float(x) for x in cells[-1].strip("[]").split(","))
        reference = _wilson(k, 2)
        assert low == pytest.approx(reference[0], abs=5e-4)  # printed to 3 decimals
        assert high == pytest.approx(reference[1], abs=5e-4)
        assert (frame["impacts"] >= 1).all()  # every run landed and was measured
    assert (tmp_path / "impact_campaign.md").read_text().startswith(lines[0])


class _Recorder:
    """The scene's controller, recording every input it receives."""

    def __init__(self, inner: Any) -> None:
        self.inner = inner
        self.robot = getattr(inner, "robot", None)  # the model the momentum observer runs on
        self.inputs: list[tuple[float, np.ndarray, np.ndarray, ContactState]] = []

    def __call__(self, t: float, q: np.ndarray, v: np.ndarray, contacts: ContactState) -> Any:
        self.inputs.append((t, q.copy(), v.copy(), contacts))
        return self.inner(t, q, v, contacts)

    def prepare_log(self, log: Any) -> None:
        self.inner.prepare_log(log)

    def record(self, log: Any) -> None:
        self.inner.record(log)


@pytest.mark.parametrize(
    ("law", "shift"), [("Brogliato", 0.0), ("reference spreading", 0.0), ("Brogliato", 3e-3)]
)
def test_the_campaigns_controllers_see_nothing_of_the_plants_impulses(
    law: str, shift: float
) -> None:
    """Replayed from q, v and the torque alone, with NaN impulses, the inputs are the same.

    With the table ``shift`` [m] higher than the controller's model believes, the replay
    computes the gaps on the believed table: the controller never sees the true one.
    """
    campaign = load_experiment("impact_campaign")
    table = campaign.scene_table("panda", law)
    table["surfaces"]["table"]["point"][2] += shift  # the plant's; the controller keeps its own
    scene = Scene.from_dict(table, base_dir=campaign.ROBOTS, default_name="panda_landing_rs")
    recorder = _Recorder(scene.build_controller())
    log = simulate(scene, recorder, duration=0.9, progress=False).log
    contact = "panda_hand_tcp/table"
    assert log.impact_times_of(contact).size >= 1  # the plant landed
    assert len(recorder.inputs) == len(log) - 1  # one call per step (control period = step)
    assert scene.sensors is not None
    believed = recorder.robot if isinstance(recorder.robot, RobotModel) else None
    seen_geometry = scene.believed_constraints()  # the table where the controller believes it
    sensors = Sensors(scene.sensors, scene.robot, seen_geometry, None, 1e-3, believed)
    n = scene.constraints.size
    nothing = np.full(n, np.nan)
    seen_contact = False
    for k, (t, q, v, contacts) in enumerate(recorder.inputs):
        tau = np.zeros(scene.robot.nv)  # the torque applied over the last step
        if k:
            tau[scene.robot.actuated] = log.u[k - 1]
        plant = ContactState(contacts.names, nothing, nothing, nothing, np.ones(n, bool), 1e-3)
        q_r, v_r, replayed = sensors.measure(log.q[k], log.v[k], plant, log.t[k], tau)
        assert t == log.t[k]
        np.testing.assert_array_equal(q_r, q)
        np.testing.assert_array_equal(v_r, v)
        for field in ("gap", "normal_velocity", "impulse", "active"):
            np.testing.assert_array_equal(getattr(replayed, field), getattr(contacts, field))
        seen_contact |= bool(contacts.impulse[contacts.names.index(contact)] > 0.0)
    assert seen_contact  # the controller did learn of the contact, from its measurements
    if shift:  # the gaps it saw are the believed table's: the true ones are `shift` smaller
        row = contacts.names.index(contact)
        data = scene.robot.model.createData()
        pin.framesForwardKinematics(scene.robot.model, data, q[: scene.robot.nq])
        true_gap, _ = scene.constraints.evaluate(data, q, v, t)
        assert true_gap[row] == pytest.approx(contacts.gap[row] - shift, abs=1e-12)


def test_brogliato_reference_by_differences_is_the_targets_velocity() -> None:
    """The campaign's Brogliato reference (differences of the logged target) against the exact."""
    campaign = load_experiment("impact_campaign")
    compare = load_experiment("impact_control_compare")
    table = campaign.scene_table("panda", "Brogliato")
    scene = Scene.from_dict(table, base_dir=campaign.ROBOTS, default_name="panda_landing_rs")
    controller = compare._TargetVelocity(scene.build_controller())  # logs the exact velocity
    log = simulate(scene, controller, duration=0.9, progress=False).log
    t_1 = log.impact_times_of("panda_hand_tcp/table")[0]
    rows = (log.t >= t_1 - 0.05) & (log.t <= t_1 + WINDOW)  # the target switches at t_1
    differences = target_velocities(log, controller.inner.task.A)
    error = np.linalg.norm(differences - log.task_velocity_desired, axis=1)[rows]
    speed = np.linalg.norm(log.task_velocity_desired[rows], axis=1).max()
    assert error.max() < 1e-2 * speed  # measured 6.5e-4 m/s against 0.50 m/s


@pytest.mark.parametrize(
    ("flags", "match"),
    [(["--runs", "0"], r"`runs` must be an integer >= 1, got 0"), (["--seed", "-1"], r"`seed`")],
)
def test_bad_flags_are_one_line_errors(
    flags: list[str], match: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    campaign = load_experiment("impact_campaign")
    with pytest.raises(SystemExit) as exit_info:
        campaign.main([*flags, "--tasks", "panda", "--laws", "impedance", "--out", str(tmp_path)])
    assert exit_info.value.code == 2
    error = capsys.readouterr().err
    assert re.search(match, error) and "Traceback" not in error
