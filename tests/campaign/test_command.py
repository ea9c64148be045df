"""The sweep command, campaign figures and worst cases (called directly, as cli.py does)."""

from __future__ import annotations

import argparse
import shlex
import socket
import textwrap

import numpy as np
import pytest

from ucontrol.campaign import SchedulerUnreachableError, apply_overrides, load
from ucontrol.campaign.command import add_sweep_parser, is_campaign, plot_campaign, run_sweep
from ucontrol.campaign.figures import worst_cases
from ucontrol.campaign.overrides import parse_assignment
from ucontrol.scene import Scene, builtin_scene
from ucontrol.simulate import simulate

CAMPAIGN = """
[campaign]
scene = "ball.toml"
duration = 0.3
seed = 2
runs = 3
metrics = ["max_penetration", "n_impacts", "final_energy"]
success = "max_penetration < 5e-4"
worst = "max_penetration"

[grid]
"contacts.0.restitution" = [0.2, 0.8]

[distributions]
"robot.q0.0" = { type = "uniform", low = 0.12, high = 0.5 }
"""


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="ucontrol")
    add_sweep_parser(parser.add_subparsers(dest="command", required=True))
    return parser


@pytest.mark.slow
def test_sweep_then_plot_and_rerun_a_worst_case(tmp_path, capsys):
    path = tmp_path / "sweep.toml"
    path.write_text(textwrap.dedent(CAMPAIGN))
    out = tmp_path / "out"
    args = _parser().parse_args(
        ["sweep", str(path), "--out", str(out), "--workers", "2", "--no-progress"]
    )
    assert not is_campaign(out)
    assert run_sweep(args) == 0
    assert is_campaign(out) and not is_campaign(tmp_path)
    printed = capsys.readouterr().out
    table = load(out)
    assert len(table) == 6 and (table["status"] == "ok").all()
    k = int(table["success"].sum())
    assert f"success {k}/6" in printed

    paths = plot_campaign(out, tmp_path / "figures")
    names = {p.name for p in paths}
    assert {
        "success_contacts_0_restitution.png",
        "success_robot_q0_0.png",
        "success_map.png",
        "metrics.png",
        "worst.md",
        "worst.csv",
    } <= names
    assert all(p.stat().st_size > 0 for p in paths)

    # worst cases: failures of the criterion first, then the largest penetration
    worst = worst_cases(out, 6)
    expected = sorted(table.itertuples(), key=lambda r: (bool(r.success), -r.max_penetration))
    assert list(worst["run_id"]) == [r.run_id for r in expected]
    # the printed command re-runs the worst run alone with the same result
    words = shlex.split(worst.loc[0, "rerun"])
    assert words[:3] == ["ucontrol", "run", "ball"]  # a built-in scene, by name
    overrides = dict(parse_assignment(words[i + 1]) for i, w in enumerate(words) if w == "--set")
    row = table.set_index("run_id").loc[worst.loc[0, "run_id"]]
    assert overrides == {
        "contacts.0.restitution": row["contacts.0.restitution"],
        "robot.q0.0": row["robot.q0.0"],
    }
    duration = float(words[words.index("--duration") + 1])
    base = Scene.from_toml(builtin_scene("ball.toml"))
    scene_table = apply_overrides({"duration": duration, **_ball_table()}, overrides)
    scene = Scene.from_dict(scene_table, base_dir=builtin_scene("ball.toml").parent)
    again = simulate(scene, progress=False).summary
    assert again["max_penetration"] == pytest.approx(row["max_penetration"], rel=1e-12)
    assert base.duration != duration  # the hint carries the campaign's duration
    assert worst.loc[0, "run_id"] in (tmp_path / "figures" / "worst.md").read_text()


def test_success_map_counts_cover_every_run(tmp_path):
    """Cell counts of the heat map partition the runs (checked on the binned table)."""
    from ucontrol.campaign.figures import _bins, _numeric

    rng = np.random.default_rng(0)
    import pandas as pd

    frame = pd.DataFrame({"a": rng.uniform(0, 1, 50), "b": rng.choice([0.1, 0.2, 0.3], 50)})
    a_codes, a_labels = _bins(_numeric(frame["a"]))
    b_codes, b_labels = _bins(_numeric(frame["b"]))
    assert len(b_labels) == 3 and len(a_labels) == 6
    counts = np.zeros((3, 6), dtype=int)
    np.add.at(counts, (np.asarray(b_codes), np.asarray(a_codes)), 1)
    assert counts.sum() == 50
    assert list(counts.sum(axis=1)) == [int((frame["b"] == v).sum()) for v in (0.1, 0.2, 0.3)]


@pytest.mark.slow
def test_sweep_with_unreachable_scheduler_fails_before_any_run(tmp_path):
    path = tmp_path / "sweep.toml"
    path.write_text(textwrap.dedent(CAMPAIGN))
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    args = _parser().parse_args(
        [
            "sweep",
            str(path),
            "--out",
            str(tmp_path / "out"),
            "--scheduler",
            f"tcp://127.0.0.1:{port}",
        ]
    )
    with pytest.raises(SchedulerUnreachableError):
        run_sweep(args)
    assert not list((tmp_path / "out" / "runs").glob("*.json"))


def _ball_table() -> dict:
    import tomllib

    return tomllib.loads(builtin_scene("ball.toml").read_text())
