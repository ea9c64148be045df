"""SIGINT, SIGTERM and SIGHUP end `ucontrol run` in one line and keep the log to that time.

Also in the first second, while the command imports Pinocchio; and when pytest itself was
started with SIGINT ignored (a background job), whose children inherit the ignored signal.
"""

from __future__ import annotations

import json
import os
import re
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import sigint_default

from ucontrol.log import Log

#: Bound on each wait for the child, in [s] (a loaded machine imports slowly).
DEADLINE_S = 120.0
#: Each signal that ends a run, with the exit status it gives (128 + its number).
EACH_SIGNAL = pytest.mark.parametrize(
    ("signum", "status"),
    [(signal.SIGTERM, 143), (signal.SIGHUP, 129), (signal.SIGINT, 130)],
    ids=["SIGTERM", "SIGHUP", "SIGINT"],
)


def _start(arguments: list[str], progress: str = "--progress") -> subprocess.Popen[bytes]:
    """``python -m ucontrol.cli ARGUMENTS`` in a session of its own, its output piped."""
    with sigint_default():  # Ctrl-C reaches it when pytest ignores SIGINT too
        return subprocess.Popen(
            [sys.executable, "-m", "ucontrol.cli", *arguments, progress],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            start_new_session=True,
        )


def _run_until_progress(out: Path, progress_steps: int) -> subprocess.Popen[bytes]:
    """`ucontrol run ball` for 10⁴ s simulated, once its progress bar passed N steps.

    Ten million steps: the run goes on for minutes (the ball steps at about 90,000 a second
    here), long past the first checkpoint (10 s of wall time) that a test waits for.
    """
    child = _start(["run", "ball", "--duration", "10000", "--out", str(out), "--dt", "1e-3"])
    assert child.stderr is not None
    seen, end = b"", time.monotonic() + DEADLINE_S
    while time.monotonic() < end:  # tqdm reports every 1000 steps: "2.00k/10.0M"
        ready, _, _ = select.select([child.stderr], [], [], 1.0)
        if ready:
            seen += os.read(child.stderr.fileno(), 4096)
            counts = re.findall(rb"([\d.]+)(k?)/10\.0M", seen)
            done = [float(n) * (1000 if k else 1) for n, k in counts]
            if done and max(done) >= progress_steps:
                return child
        if child.poll() is not None:
            break
    os.killpg(child.pid, signal.SIGKILL)
    pytest.fail(f"the run did not start within {DEADLINE_S} s: {seen[-500:]!r}")


@pytest.mark.slow
@EACH_SIGNAL
def test_a_signal_keeps_the_log_up_to_its_time(
    tmp_path: Path, signum: signal.Signals, status: int
) -> None:
    child = _run_until_progress(tmp_path, 2000)
    child.send_signal(signum)
    try:
        _, err = child.communicate(timeout=DEADLINE_S)
    finally:
        if child.poll() is None:
            os.killpg(child.pid, signal.SIGKILL)
    assert child.returncode == status, err
    message = err.decode().strip().splitlines()[-1]
    match = re.fullmatch(
        rf"ucontrol: interrupted by {signum.name}; the log up to t = ([\d.e+-]+) s is in (.*)",
        message,
    )
    assert match is not None, message
    log = Log.load(match.group(2))
    assert log.t[-1] == pytest.approx(float(match.group(1)), abs=1e-9)
    assert log.t[-1] >= 2.0  # the run had passed 2000 steps of 1 ms
    np.testing.assert_allclose(np.diff(log.t), 1e-3, rtol=1e-9)  # every row up to it
    assert np.all(np.isfinite(log.q))
    summary = json.loads((tmp_path / "summary.json").read_text())  # of the rows up to it
    assert summary["interrupted"] is True and summary["interrupted_by"] == signum.name
    assert summary["final_time"] == log.t[-1] and summary["steps"] == len(log) - 1


@pytest.mark.slow
def test_sigterm_after_a_checkpoint_keeps_the_rows_since(tmp_path: Path) -> None:
    """The periodic checkpoint (every 10 s of wall time) does not cap what a signal keeps."""
    child = _run_until_progress(tmp_path, 1000)
    end = time.monotonic() + DEADLINE_S
    while not (tmp_path / "log.npz").exists() and time.monotonic() < end:
        time.sleep(0.2)
    checkpoint = Log.load(tmp_path / "log.npz")
    time.sleep(1.0)
    child.send_signal(signal.SIGTERM)
    try:
        _, err = child.communicate(timeout=DEADLINE_S)
    finally:
        if child.poll() is None:
            os.killpg(child.pid, signal.SIGKILL)
    assert child.returncode == 143, err
    log = Log.load(tmp_path / "log.npz")
    assert log.t[-1] > checkpoint.t[-1]  # the rows after the checkpoint are kept
    np.testing.assert_array_equal(log.q[: len(checkpoint)], checkpoint.q[: len(checkpoint)])


def _caught_signals(pid: int) -> int:
    """The mask of the signals process ``pid`` handles (Linux ``/proc/PID/status``)."""
    status = Path(f"/proc/{pid}/status").read_text()
    return int(re.search(r"^SigCgt:\s*([0-9a-f]+)$", status, re.M).group(1), 16)  # type: ignore[union-attr]


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="needs Linux /proc")
@EACH_SIGNAL
def test_a_signal_at_start_up_ends_in_one_line(
    tmp_path: Path, signum: signal.Signals, status: int
) -> None:
    """Sent as soon as the command handles SIGTERM, i.e. while it still imports."""
    command = ["run", "ball", "--duration", "1000", "--out", str(tmp_path / "out")]
    child = _start(command, "--no-progress")
    try:
        end = time.monotonic() + DEADLINE_S
        while not _caught_signals(child.pid) >> (signal.SIGTERM - 1) & 1:
            assert child.poll() is None and time.monotonic() < end, "no SIGTERM handler"
            time.sleep(1e-3)
        child.send_signal(signum)
        _, err = child.communicate(timeout=DEADLINE_S)
    finally:
        if child.poll() is None:
            os.killpg(child.pid, signal.SIGKILL)
    lines = err.decode().strip().splitlines()
    assert child.returncode == status and len(lines) == 1, err.decode()
    assert re.fullmatch(rf"ucontrol: interrupted by {signum.name}; .*", lines[0]), lines


def test_the_signals_are_handled_before_pinocchio_is_imported(tmp_path: Path) -> None:
    """An audit hook in the child records the SIGTERM and SIGHUP handlers at that import."""
    script = f"""
import signal, sys
seen = []
def hook(event, args):
    if event == "import" and args[0] == "pinocchio" and not seen:
        seen.append([signal.getsignal(s) is not signal.SIG_DFL for s in (15, 1)])
sys.addaudithook(hook)
from ucontrol.cli import main
status = main(["run", "ball", "--duration", "0.01", "--out", {str(tmp_path)!r}])
print(status, seen)
"""
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=DEADLINE_S
    )
    assert done.stdout.strip().splitlines()[-1] == "0 [[True, True]]", done.stderr


#: The tests that send SIGINT to a child, run by a pytest that ignores SIGINT.
SIGINT_TESTS = (
    "tests/test_signals.py::test_a_signal_keeps_the_log_up_to_its_time[SIGINT]",
    "tests/test_signals.py::test_a_signal_at_start_up_ends_in_one_line[SIGINT]",
    "tests/campaign/test_interrupt.py::"
    "test_signal_writes_the_table_and_a_rerun_completes_every_run_once[SIGINT]",
)


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_the_sigint_tests_pass_when_pytest_ignores_sigint() -> None:
    """``trap '' INT`` as a shell gives a background job; exec keeps the ignored signal."""
    root = Path(__file__).resolve().parents[1]
    shell = "trap '' INT; exec \"$@\""
    check = "import signal; print(signal.getsignal(signal.SIGINT) == signal.SIG_IGN)"
    python = [sys.executable, "-c", check]
    ignored = subprocess.run(
        ["sh", "-c", shell, "sh", *python], capture_output=True, text=True, timeout=60
    )
    assert ignored.stdout.strip() == "True"  # SIGINT ignored: as the pytest below starts
    pytest_run = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *SIGINT_TESTS]
    done = subprocess.run(
        ["sh", "-c", shell, "sh", *pytest_run],
        cwd=root,
        capture_output=True,
        text=True,
        timeout=840,
    )
    assert done.returncode == 0 and "3 passed" in done.stdout, done.stdout[-3000:]
