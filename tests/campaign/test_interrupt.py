"""SIGTERM or Ctrl-C of a campaign: the table is written, the cluster stops, a re-run finishes."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from conftest import sigint_default

from ucontrol.campaign import load

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out

CAMPAIGN = """
[campaign]
scene = "ball.toml"
duration = 2.0  # [s] per run: the signal lands long before the 8 runs are done
dt = 2e-4
seed = 4
runs = 8
metrics = ["n_impacts", "max_penetration"]

[distributions]
"contacts.0.restitution" = { type = "uniform", low = 0.2, high = 0.9 }
"""
TIMEOUT_S = 120.0


def _start(path: Path, out: Path) -> subprocess.Popen[str]:
    """``python -m ucontrol.campaign`` in its own process group (one local worker)."""
    command = [sys.executable, "-m", "ucontrol.campaign", str(path), "--out", str(out)]
    with sigint_default():  # Ctrl-C reaches it when pytest ignores SIGINT too
        return subprocess.Popen(
            [*command, "--workers", "1", "--no-progress"],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            start_new_session=True,
        )


def _finish(process: subprocess.Popen[str]) -> tuple[int, str]:
    """Wait for the process (bounded); kill its whole group if it outlives the timeout."""
    try:
        output, _ = process.communicate(timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        output, _ = process.communicate()
        pytest.fail(f"campaign did not stop within {TIMEOUT_S} s:\n{output}")
    return process.returncode, output


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_signal_writes_the_table_and_a_rerun_completes_every_run_once(tmp_path, signum):
    """SIGTERM goes to the client alone; SIGINT to the whole group, as Ctrl-C in a terminal."""
    path = tmp_path / "interrupt.toml"
    path.write_text(textwrap.dedent(CAMPAIGN))
    out = tmp_path / "out"
    process = _start(path, out)
    try:
        deadline = time.monotonic() + TIMEOUT_S
        while len(list((out / "runs").glob("run-*.json"))) < 2:
            assert process.poll() is None, process.communicate()[0]
            assert time.monotonic() < deadline, "no run finished in time"
            time.sleep(0.05)
        if signum == signal.SIGTERM:
            process.send_signal(signal.SIGTERM)
        else:
            os.killpg(process.pid, signal.SIGINT)
        status, output = _finish(process)
        # the worker processes of the local cluster went with the client
        deadline = time.monotonic() + 30.0
        while _group_alive(process.pid) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not _group_alive(process.pid), "cluster processes outlived the client"
    finally:
        if _group_alive(process.pid):
            os.killpg(process.pid, signal.SIGKILL)
    assert status == 128 + signum, output  # 143 for SIGTERM, 130 for Ctrl-C
    assert "interrupted" in output
    done = {p.name: p.read_bytes() for p in (out / "runs").glob("run-*.json")}
    assert 2 <= len(done) < 8, output
    table = load(out)
    csv_rows = (out / "campaign.csv").read_text().splitlines()[1:]
    assert len(csv_rows) == len(table) == len(done)  # the table holds what ran, no more

    rerun = _start(path, out)
    try:
        status, output = _finish(rerun)
    finally:
        if _group_alive(rerun.pid):
            os.killpg(rerun.pid, signal.SIGKILL)
    assert status == 0, output
    table = load(out)
    assert sorted(table["run_id"]) == [f"run-{i:05d}" for i in range(8)]
    assert table["run_id"].is_unique and (table["status"] == "ok").all()
    for name, content in done.items():  # runs finished before the signal were not run again
        assert (out / "runs" / name).read_bytes() == content
    assert f"{len(done)} already done, {8 - len(done)} ran now" in output
