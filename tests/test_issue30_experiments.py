"""experiments/cli_run_speed.py and experiments/mujoco_peer.py (issue 30's measurements).

The first runs briefly (a smoke test; no time is asserted); the second's MJCF Panda is checked
against Pinocchio's dynamics, where MuJoCo is installed.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import load_experiment

import ucontrol
from ucontrol.exceptions import URDFError
from ucontrol.model import example_robot_data_dir

pytestmark = pytest.mark.slow  # subprocesses and whole runs


def test_cli_run_speed_runs(capsys: pytest.CaptureFixture[str]) -> None:
    speed = load_experiment("cli_run_speed")
    figures = speed.main(["--scenes", "default", "--rounds", "1"])
    default = figures["default"]
    assert default["command_cpu_s"] > 0.0 and default["command_wall_s"] > 0.0
    assert all(default[key] > 0.0 for key in ("rtf_wall", "rtf_cpu", "in_process_rtf_cpu"))
    assert "| default |" in capsys.readouterr().out


def test_cli_run_speed_runs_a_baseline_from_its_interpreter(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """``--baseline-python``: the baseline as ``PYTHON -m ucontrol.cli`` (here this tree's)."""
    speed = load_experiment("cli_run_speed")
    tree = str(Path(ucontrol.__file__).parents[1])
    speed.main(
        ["--scenes", "default", "--rounds", "1", "--baseline", tree, "--baseline-python",
         sys.executable]
    )  # fmt: skip
    out = capsys.readouterr().out
    assert f"| scene | command CPU, {tree} [s] | this tree [s] |" in out
    assert out.count("| default |") == 2  # the figures' table and the baseline's


def test_mujoco_peer_is_the_same_robot() -> None:
    """The MJCF of the step benchmark's Panda: Pinocchio's M(q) and h(q, v), the 4 contacts."""
    pytest.importorskip("mujoco")
    try:
        example_robot_data_dir()
    except URDFError:
        pytest.skip("example-robot-data is not installed (extra `robots`)")
    import mujoco

    bench, peer = load_experiment("bench_step"), load_experiment("mujoco_peer")
    robot, contacts, _ = bench.panda_setup(4)
    model = mujoco.MjModel.from_xml_string(peer.mjcf_of(robot.model, contacts, 1e-3))
    data = mujoco.MjData(model)
    rng = np.random.default_rng(3)
    for _ in range(3):
        q, v = bench.Q0 + 0.2 * rng.standard_normal(9), rng.standard_normal(9)
        data.qpos[:], data.qvel[:] = q, v
        mujoco.mj_forward(model, data)
        M = np.zeros((9, 9))
        mujoco.mj_fullM(model, data, M)
        np.testing.assert_allclose(M, robot.mass_matrix(q), atol=1e-12)
        np.testing.assert_allclose(data.qfrc_bias, robot.nonlinear_effects(q, v), atol=1e-11)
    data.qpos[:], data.qvel[:] = bench.Q0, 0.0
    mujoco.mj_forward(model, data)
    assert data.ncon == 4  # every sphere overlaps the table by OVERLAP at the start
    np.testing.assert_allclose([data.contact[i].dist for i in range(4)], -bench.OVERLAP, atol=1e-9)
