"""Outputs that are never lost nor corrupt: atomic writes, a full disk, concurrent runs."""

from __future__ import annotations

import contextlib
import errno
import io
import multiprocessing
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import ucontrol.output_files as output_files
import ucontrol.simulate as simulate_module
from ucontrol.cli import main
from ucontrol.exceptions import OutputInUseError, OutputPathError, OutputWriteError
from ucontrol.log import Log
from ucontrol.output_files import OutputLock, check_output_dir, check_output_file
from ucontrol.scene import load_scene
from ucontrol.simulate import simulate


def test_output_locations_are_checked_before_any_work(tmp_path: Path) -> None:
    file = tmp_path / "file"
    file.write_text("x")
    with pytest.raises(OutputPathError, match=r"it is a file, not a directory.*file'"):
        check_output_dir("out", file)
    with pytest.raises(OutputPathError, match=r"/dev/null"):
        check_output_dir("out", "/dev/null")
    with pytest.raises(OutputPathError, match=r"it is a directory"):
        check_output_file("--html", tmp_path)
    with pytest.raises(OutputPathError, match=r"not writable|Permission|Not a directory"):
        check_output_dir("out", file / "below")
    assert check_output_dir("out", tmp_path / "new" / "dir").is_dir()
    calls = []
    with pytest.raises(OutputPathError):  # nothing was simulated
        simulate(load_scene("ball"), lambda *a: calls.append(a) or [0.0], out=file)
    assert calls == []


def test_a_full_disk_keeps_the_last_checkpoint_and_no_temporary_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(simulate_module, "CHECKPOINT_PERIOD_S", -1.0)  # every 1000 steps
    saved = []
    real_fsync = os.fsync

    def fsync(descriptor: int) -> None:
        if len(saved) >= 2:  # the third write finds the disk full
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        saved.append(descriptor)
        real_fsync(descriptor)

    monkeypatch.setattr(output_files.os, "fsync", fsync)
    with pytest.raises(OutputWriteError, match=r"No space left on device") as caught:
        simulate(load_scene("ball"), duration=5.0, out=tmp_path)
    assert caught.value.path == str(tmp_path / "log.npz")
    log = Log.load(tmp_path / "log.npz")  # the second checkpoint (after step 1000), whole
    assert log.t[-1] == pytest.approx(1.0, abs=1e-9) and len(log) == 1001
    assert sorted(p.name for p in tmp_path.iterdir()) == ["log.npz"]  # no temporary, no lock


def test_write_atomically_keeps_the_previous_file_when_the_writer_fails(tmp_path: Path) -> None:
    target = tmp_path / "data.bin"
    output_files.write_atomically(target, lambda stream: stream.write(b"first"))

    def broken(stream: io.BufferedWriter) -> None:
        stream.write(b"half")
        raise RuntimeError("writer failed")

    with pytest.raises(RuntimeError):
        output_files.write_atomically(target, broken)
    assert target.read_bytes() == b"first" and [p.name for p in tmp_path.iterdir()] == ["data.bin"]


def test_a_directory_in_use_is_refused_and_a_stale_lock_taken_over(tmp_path: Path) -> None:
    (tmp_path / output_files.LOCK_FILE).write_text("1")  # pid 1 runs: the directory is in use
    with pytest.raises(OutputInUseError, match=r"in use by the run of process 1"):
        simulate(load_scene("ball"), duration=0.01, out=tmp_path)
    stale = 2**22 + 17  # above the kernel's default pid_max: no such process
    (tmp_path / output_files.LOCK_FILE).write_text(str(stale))
    simulate(load_scene("ball"), duration=0.01, out=tmp_path)
    assert not (tmp_path / output_files.LOCK_FILE).exists()
    lock = OutputLock(tmp_path)
    with lock.held():
        assert (tmp_path / output_files.LOCK_FILE).read_text() == str(os.getpid())
    assert not (tmp_path / output_files.LOCK_FILE).exists()


@pytest.mark.parametrize("content", ["0", "-1", "1099511627776", "not a pid"])
def test_a_lock_without_a_possible_process_id_is_taken_over(tmp_path: Path, content: str) -> None:
    """A lock holding no possible process id is stale and taken over.

    0 and -1 would name this process group or every process to os.kill, and 2**40 overflows it.
    """
    (tmp_path / output_files.LOCK_FILE).write_text(content)
    simulate(load_scene("ball"), duration=0.01, out=tmp_path)
    assert (tmp_path / "log.npz").is_file()
    assert not (tmp_path / output_files.LOCK_FILE).exists()


def _one_run(out: str, report: str, barrier: Any) -> None:
    """A child process: `ucontrol run ball` into the shared directory, its output to a file."""
    with open(report, "w") as stream, contextlib.redirect_stdout(stream):
        with contextlib.redirect_stderr(stream):
            barrier.wait(timeout=60)
            status = main(["run", "ball", "--duration", "0.5", "--out", out, "--no-progress"])
    sys.exit(status)


@pytest.mark.slow
@pytest.mark.skipif(sys.platform != "linux", reason="fork start method")
def test_two_simultaneous_runs_never_report_a_log_they_did_not_write(tmp_path: Path) -> None:
    context = multiprocessing.get_context("fork")
    outcomes = {"both": 0, "one refused": 0}
    for trial in range(20):
        out = tmp_path / f"trial{trial}"
        barrier = context.Barrier(2)
        reports = [tmp_path / f"trial{trial}.{i}.txt" for i in range(2)]
        children = [
            context.Process(target=_one_run, args=(str(out), str(report), barrier))
            for report in reports
        ]
        for child in children:
            child.start()
        for child in children:
            child.join(timeout=120)
            if child.is_alive():
                child.kill()
                pytest.fail(f"trial {trial}: a run did not end")
        texts = [report.read_text() for report in reports]
        statuses = [child.exitcode for child in children]
        assert sorted(statuses) in ([0, 0], [0, 2]), (statuses, texts)
        for status, text in zip(statuses, texts):
            if status == 2:
                assert "is in use by the run of process" in text
            else:
                assert "wrote" in text
        log = Log.load(out / "log.npz")  # whole, and complete
        assert len(log) == 501 and np.all(np.isfinite(log.q))
        outcomes["both" if statuses == [0, 0] else "one refused"] += 1
        assert sorted(p.name for p in out.iterdir()) == ["log.npz", "summary.json"]
    assert sum(outcomes.values()) == 20, outcomes
