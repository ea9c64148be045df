"""Children of the viewers end with their process group and leave no files behind.

Chromium forks renderer and GPU processes that may still write in its profile after the main
process exits; a meshcat server must not outlive the process that started it, even killed.
These tests stand for them with small shell and Python programs.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from ucontrol.viz.browser_screenshot import group_alive, remove_tree, run_group

pytestmark = pytest.mark.timeout(300)

#: A leader that exits at once, leaving a grandchild in its group that keeps writing files.
LATE_WRITER = "(while :; do touch {folder}/late.$$.$RANDOM; sleep 0.01; done) & sleep 0.2; exit 3"


def _wait_until(condition: object, timeout: float) -> bool:
    """Poll ``condition()`` every 50 ms for at most ``timeout`` [s]; its last value."""
    deadline = time.monotonic() + timeout
    while not condition():  # type: ignore[operator]
        if time.monotonic() > deadline:
            return False
        time.sleep(0.05)
    return True


def test_a_group_is_killed_with_its_late_writers_and_its_folder_removed(tmp_path: Path) -> None:
    profile = tmp_path / "profile"
    profile.mkdir()
    logs = tmp_path / "logs"
    logs.mkdir()
    command = ["sh", "-c", LATE_WRITER.format(folder=profile)]
    outcome = run_group(command, timeout=60.0, folder=logs)
    assert outcome.startswith("exit status 3")
    assert any(profile.iterdir())  # the grandchild wrote, also after the leader's exit
    remove_tree(profile)
    assert not profile.exists()


def test_a_hung_group_is_killed_at_its_timeout(tmp_path: Path) -> None:
    marker = tmp_path / "pids"
    command = ["sh", "-c", f"sleep 300 & echo $$ $! > {marker}; wait"]
    outcome = run_group(command, timeout=1.0, folder=tmp_path)
    assert outcome.startswith("no exit within 1 s")
    leader, child = (int(pid) for pid in marker.read_text().split())
    assert not group_alive(leader)
    assert not Path(f"/proc/{child}").exists() or "Z" in _state(child)


def _state(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[0]
    except OSError:
        return "gone"


CLIENT = """
import sys, time
from ucontrol.viz.meshcat_server import MeshcatServer
server = MeshcatServer()
print(server._process.pid, flush=True)
time.sleep(600)
"""


def test_a_meshcat_server_ends_when_its_client_is_killed() -> None:
    client = subprocess.Popen(
        [sys.executable, "-c", CLIENT], stdout=subprocess.PIPE, text=True, start_new_session=True
    )
    try:
        assert client.stdout is not None
        server = int(client.stdout.readline())  # bounded by the test's timeout
        assert group_alive(server)
        os.kill(client.pid, signal.SIGKILL)  # no atexit, no close()
        client.wait(timeout=60)
        assert _wait_until(lambda: not group_alive(server), timeout=60.0)
    finally:
        if client.poll() is None:
            client.kill()
            client.wait()
