"""Campaign runs on a two-worker LocalCluster: metrics, failures, resume, killed workers."""

from __future__ import annotations

import json
import math
import textwrap
import tomllib
from pathlib import Path

import numpy as np
import pytest

from ucontrol.campaign import (
    CampaignMismatchError,
    load,
    load_campaign,
    run_campaign,
)
from ucontrol.campaign.runner import CLUSTER_SETTINGS
from ucontrol.campaign.table import check_formats, finished_runs
from ucontrol.exceptions import OptionalDependencyError
from ucontrol.scene import Scene, builtin_scene
from ucontrol.simulate import simulate

G = 9.81  # [m/s^2], the ball scene's gravity
RADIUS = 0.1  # [m], the ball's contact radius

METRICS_MODULE = '''
"""User metrics of the campaign tests."""
import os
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent


def first_impact_time(result):
    """Time of the first impulse [s], NaN without impact."""
    hit = np.flatnonzero(result.log.impulse[:, 0] > 0.0)
    return float(result.log.t[hit[0]]) if hit.size else float("nan")


def kill_flagged(result):
    """Kill the worker process on flagged runs: q0 = 0.137 once, q0 = 0.171 every time."""
    q0 = float(result.log.q[0, 0])
    if abs(q0 - 0.137) < 1e-12:
        marker = HERE / "killed-once"
        if not marker.exists():
            marker.write_text("x")
            os._exit(1)
    if abs(q0 - 0.171) < 1e-12:
        os._exit(1)
    return q0
'''


@pytest.fixture(scope="module")
def client():
    """One LocalCluster of two single-threaded worker processes for the module."""
    import dask
    from distributed import Client, LocalCluster

    with dask.config.set(CLUSTER_SETTINGS):  # as run_campaign's own local cluster
        cluster = LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0",
            silence_logs=50,
        )
    dask_client = Client(cluster)
    yield dask_client
    dask_client.close()
    cluster.close()


def _campaign(
    tmp_path: Path, body: str, name: str = "campaign.toml", module: str = "user_metrics"
) -> Path:
    """Write a campaign file and the user-metrics module.

    Each test names its own module: workers keep the modules they imported.
    """
    (tmp_path / f"{module}.py").write_text(METRICS_MODULE)
    path = tmp_path / name
    path.write_text(textwrap.dedent(body))
    return path


def test_metrics_match_direct_runs_and_the_free_fall(client, tmp_path):
    path = _campaign(
        tmp_path,
        """
        [campaign]
        scene = "ball.toml"
        duration = 0.2
        seed = 5
        runs = 2
        metrics = ["max_penetration", "n_impacts", "final_energy"]
        success = "n_impacts >= 1 and max_penetration < 1e-3"

        [metrics]
        t_hit = "user_metrics:first_impact_time"

        [grid]
        "robot.q0.0" = [0.05, 0.12, 0.15]

        [distributions]
        "contacts.0.restitution" = { type = "uniform", low = 0.0, high = 0.95 }
        """,
    )
    campaign = load_campaign(path)
    outcome = run_campaign(campaign, tmp_path / "out", client=client)
    assert (outcome.total, outcome.ran, outcome.skipped) == (6, 6, 0)
    table = load(tmp_path / "out")
    assert sorted(table["run_id"]) == [f"run-{i:05d}" for i in range(6)]
    base = tomllib.loads(builtin_scene("ball.toml").read_text())
    for _, row in table.iterrows():
        q0 = row["robot.q0.0"]
        if q0 < RADIUS:  # starts inside the ground: the run raises, recorded with its text
            assert row["status"] == "error" and "penetrates" in row["error"]
            assert not row["success"]
            continue
        assert row["status"] == "ok", row["error"]
        # independent reference: the same scene edited by hand and run directly
        table_direct = tomllib.loads(builtin_scene("ball.toml").read_text())
        table_direct["duration"] = 0.2
        table_direct["robot"]["q0"] = [q0]
        table_direct["contacts"][0]["restitution"] = row["contacts.0.restitution"]
        scene = Scene.from_dict(table_direct, base_dir=builtin_scene("ball.toml").parent)
        direct = simulate(scene, progress=False).summary
        for name in ("max_penetration", "n_impacts", "final_energy"):
            assert row[name] == pytest.approx(direct[name], rel=1e-12, abs=1e-15)
        # free fall from the gap q0 - r: first impulse within one step of sqrt(2 gap / g)
        dt = base["integrator"]["dt"]
        assert abs(row["t_hit"] - math.sqrt(2.0 * (q0 - RADIUS) / G)) <= 1.5 * dt
        assert row["success"] == (direct["n_impacts"] >= 1 and direct["max_penetration"] < 1e-3)


def test_resume_runs_only_the_missing_runs(client, tmp_path):
    path = _campaign(
        tmp_path,
        """
        [campaign]
        scene = "ball.toml"
        duration = 0.1
        seed = 1
        runs = 6
        metrics = ["n_impacts", "final_energy"]

        [distributions]
        "robot.q0.0" = { type = "uniform", low = 0.11, high = 0.15 }
        """,
    )
    out = tmp_path / "out"
    first = run_campaign(load_campaign(path), out, client=client)
    assert first.ran == 6
    runs = out / "runs"
    before = {p.name: p.read_bytes() for p in runs.glob("*.json")}
    for name in ("run-00001.json", "run-00004.json"):
        (runs / name).unlink()
    second = run_campaign(load_campaign(path), out, client=client)
    assert (second.skipped, second.ran, second.failed) == (4, 2, 0)
    after = {p.name: p.read_bytes() for p in runs.glob("*.json")}
    assert sorted(after) == sorted(before)
    for name, content in before.items():  # untouched runs were not run again
        if name not in ("run-00001.json", "run-00004.json"):
            assert after[name] == content
    table = load(out)
    assert table["run_id"].is_unique and len(table) == 6
    # the re-run draws are the same as the first time (run ids from seed and index)
    for name in ("run-00001.json", "run-00004.json"):
        old, new = json.loads(before[name]), json.loads(after[name])
        assert old["parameters"] == new["parameters"]
        assert old["metrics"] == new["metrics"]  # deterministic runs: identical metrics
    csv = (out / "campaign.csv").read_text().splitlines()
    assert len(csv) == 7
    third = run_campaign(load_campaign(path), out, client=client)
    assert (third.ran, third.skipped) == (0, 6)


def test_another_campaign_in_the_same_directory_is_refused(client, tmp_path):
    body = """
        [campaign]
        scene = "ball.toml"
        duration = 0.05
        [grid]
        "contacts.0.restitution" = [VALUE]
        """
    first = _campaign(tmp_path, body.replace("VALUE", "0.5"), "a.toml")
    run_campaign(load_campaign(first), tmp_path / "out", client=client)
    second = _campaign(tmp_path, body.replace("VALUE", "0.6"), "b.toml")
    with pytest.raises(CampaignMismatchError):
        run_campaign(load_campaign(second), tmp_path / "out", client=client)


def test_parquet_without_pyarrow_is_a_typed_error():
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        with pytest.raises(OptionalDependencyError, match="pyarrow"):
            check_formats(("csv", "parquet"))
    else:
        check_formats(("csv", "parquet"))


#: Runs whose metric kills the worker at q0 = 0.137 (once) and 0.171 (every time).
KILL_CAMPAIGN = """
    [campaign]
    scene = "ball.toml"
    duration = 0.05

    [metrics]
    q0 = "kill_metrics:kill_flagged"

    [grid]
    "robot.q0.0" = [VALUES]
    """


@pytest.mark.slow
def test_killed_worker_run_is_retried_once_then_recorded(client, tmp_path):
    once = _campaign(
        tmp_path, KILL_CAMPAIGN.replace("VALUES", "0.12, 0.137, 0.15"), "once.toml", "kill_metrics"
    )
    outcome = run_campaign(load_campaign(once), tmp_path / "once", client=client)
    assert (tmp_path / "killed-once").exists()  # the worker did die once
    table = load(tmp_path / "once")
    assert table["run_id"].is_unique and len(table) == 3
    row = table.set_index("run_id").loc["run-00001"]
    assert row["status"] == "ok" and row["q0"] == pytest.approx(0.137)  # retried, then done
    assert outcome.total == 3

    always = _campaign(
        tmp_path,
        KILL_CAMPAIGN.replace("VALUES", "0.12, 0.171, 0.15"),
        "always.toml",
        "kill_metrics",
    )
    run_campaign(load_campaign(always), tmp_path / "always", client=client)
    table = load(tmp_path / "always").set_index("run_id")
    assert sorted(table.index) == ["run-00000", "run-00001", "run-00002"]
    killed = table.loc["run-00001"]
    assert killed["status"] == "killed" and "KilledWorker" in killed["error"]
    assert not killed["success"]
    # every other run completed: a worker holds only the run it executes
    for run_id in ("run-00000", "run-00002"):
        assert table.loc[run_id, "status"] == "ok"
    assert set(finished_runs(tmp_path / "always")) == set(table.index)
    assert np.isnan(killed["wall_time_s"])


@pytest.mark.timeout(300)  # a lost worker stalled the campaign: bounded, not timed
def test_one_worker_killed_twice_takes_only_its_run(tmp_path):
    """The run that kills its worker, twice, is recorded killed; the others all complete.

    One worker, in the local cluster run_campaign starts itself.
    """
    values = "0.12, 0.13, 0.171, 0.15, 0.16, 0.17, 0.18, 0.19"
    path = _campaign(
        tmp_path, KILL_CAMPAIGN.replace("VALUES", values), "one_worker.toml", "kill_metrics"
    )
    outcome = run_campaign(load_campaign(path), tmp_path / "out", workers=1, progress=False)
    assert (outcome.total, outcome.ran, outcome.failed) == (8, 8, 1)
    assert not outcome.interrupted
    table = load(tmp_path / "out").set_index("run_id")
    assert table.loc["run-00002", "status"] == "killed"
    assert "2 different workers" in table.loc["run-00002", "error"]
    others = table.drop(index="run-00002")
    assert len(others) == 7 and (others["status"] == "ok").all()
    np.testing.assert_allclose(others["q0"], [0.12, 0.13, 0.15, 0.16, 0.17, 0.18, 0.19])


@pytest.mark.timeout(120)  # it waited for a worker forever
def test_a_campaign_without_workers_stops_after_the_timeout(tmp_path):
    """Every worker gone (a scheduler whose workers died): interrupted with the reason."""
    from distributed import Client, LocalCluster

    path = _campaign(tmp_path, KILL_CAMPAIGN.replace("VALUES", "0.12, 0.13"), "none.toml")
    cluster = LocalCluster(n_workers=0, processes=True, dashboard_address=":0")
    try:
        with Client(cluster) as no_workers:
            outcome = run_campaign(
                load_campaign(path, check=False),
                tmp_path / "out",
                client=no_workers,
                worker_timeout=1.0,
            )
    finally:
        cluster.close()
    assert outcome.interrupted and (outcome.total, outcome.ran, outcome.signum) == (2, 0, None)
    assert outcome.reason == "no Dask worker connected for 1 s with 2 run(s) pending"
    assert load(tmp_path / "out").empty  # the table is written, empty: resume runs both


def test_runs_on_an_existing_scheduler_by_address(client, tmp_path):
    """``--scheduler ADDRESS``: a client of its own connects, runs, and brings records back."""
    path = _campaign(
        tmp_path,
        """
        [campaign]
        scene = "ball.toml"
        duration = 0.05
        [grid]
        "contacts.0.restitution" = [0.1, 0.4, 0.7]
        """,
    )
    address = client.scheduler.address
    outcome = run_campaign(load_campaign(path), tmp_path / "out", scheduler=address)
    assert (outcome.ran, outcome.failed) == (3, 0)
    assert sorted(load(tmp_path / "out")["contacts.0.restitution"]) == [0.1, 0.4, 0.7]
    assert client.status == "running"  # the cluster is not ours to close
