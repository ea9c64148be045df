"""Screenshots of viewer pages in headless Chromium (Debian's ``chromium``), for tests and docs.

Every launch is bounded and leaves nothing behind: Chromium runs in a process group of its
own (``start_new_session``), which is killed as a whole once the main process has exited or
overrun :data:`TIMEOUT` (its renderer, GPU and zygote children included); its output goes to
files, never to a pipe that could fill; its profile folder is removed after the group is
dead, tolerating files a late writer still creates (the removal is retried, then left to the
system's temporary-file cleanup rather than raised).
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from ucontrol.exceptions import ViewerError

#: Flags of a headless, software-rendered Chromium that opens no connection of its own.
CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--use-gl=swiftshader",
    "--enable-unsafe-swiftshader",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
)
#: Longest wait for one browser launch, in [s]; a launch that overruns it is killed.
TIMEOUT = 60.0
#: Browser launches tried per screenshot: headless Chromium intermittently never ends its
#: virtual-time budget, or writes the screenshot and then never exits, and a live page may be
#: shot before its scene has arrived through the websocket (``ready`` rejects it). The last
#: launch runs in real time instead (``--timeout``), which Chromium always ends.
ATTEMPTS = 4
#: Real time a real-time launch gives the page beyond the virtual time asked, in [ms].
REAL_TIME_MARGIN_MS = 3000
#: Longest wait for the processes of a killed group to be gone, in [s].
GROUP_EXIT_TIMEOUT = 10.0
#: Removals of a profile folder tried while late writers may still add files to it.
REMOVE_ATTEMPTS = 5
#: Pause between two removal attempts, in [s].
REMOVE_PAUSE = 0.2
#: Last bytes of every complete PNG file (the IEND chunk with its CRC).
PNG_END = b"IEND\xaeB`\x82"


def find_chromium() -> str | None:
    """Path of the ``chromium`` executable, or None when it is not installed."""
    return shutil.which("chromium")


def screenshot(
    url: str,
    out: str | Path,
    *,
    width: int = 800,
    height: int = 600,
    virtual_time_ms: int = 1500,
    offline: bool = False,
    ready: Callable[[Path], bool] | None = None,
) -> Path:
    """Load ``url`` in headless Chromium and write a PNG screenshot of the page.

    Args:
        url: Page address (``http://`` for a live viewer, ``file://`` for an exported page).
        out: PNG file to write.
        width: Width of the window in [px].
        height: Height of the window in [px].
        virtual_time_ms: Virtual time the page runs before the shot, in [ms]; a meshcat
            animation has then played this long.
        offline: Send every network request to a closed port: the page must need none.
        ready: Check of a complete screenshot, e.g. that the scene of a live viewer has
            arrived; a shot it rejects is taken again, within the :data:`ATTEMPTS` launches.

    Returns:
        The path written.

    Raises:
        ViewerError: chromium is not installed, or no launch of :data:`ATTEMPTS` gave a
            complete screenshot that ``ready`` accepts.
    """
    executable = find_chromium()
    if executable is None:
        raise ViewerError("chromium is not installed (Debian: apt-get install -y chromium)")
    out = Path(out).resolve()
    errors = []
    for attempt in range(ATTEMPTS):
        out.unlink(missing_ok=True)
        if attempt < ATTEMPTS - 1:
            clock = f"--virtual-time-budget={virtual_time_ms}"
        else:  # the page plays for at least as long, in real time
            clock = f"--timeout={virtual_time_ms + REAL_TIME_MARGIN_MS}"
        profile = tempfile.mkdtemp(prefix="ucontrol-chromium-")
        try:
            flags = [
                *CHROMIUM_FLAGS,
                f"--user-data-dir={profile}",
                f"--window-size={width},{height}",
            ]
            if offline:
                flags += ["--proxy-server=127.0.0.1:9", "--proxy-bypass-list=<-loopback>"]
            command = [executable, *flags, clock, f"--screenshot={out}", url]
            errors.append(run_group(command, TIMEOUT, Path(profile)))
        finally:
            remove_tree(Path(profile))
        if _is_complete_png(out):
            if ready is None or ready(out):
                return out
            errors.append("the page was not ready (its scene had not arrived)")
    raise ViewerError(f"chromium failed {ATTEMPTS} times on {url}; last: {errors[-1]}")


def run_group(command: list[str], timeout: float, folder: Path) -> str:
    """Run ``command`` in a new process group, bounded by ``timeout``, and kill the group.

    Args:
        command: Program and arguments.
        timeout: Longest wait for the main process, in [s].
        folder: Existing folder for the output files of the process.

    Returns:
        How the process ended and the end of its error output, for error messages.
    """
    with (
        open(folder / "stdout.txt", "w+b") as stdout,
        open(folder / "stderr.txt", "w+b") as stderr,
    ):
        process = subprocess.Popen(
            command, stdin=subprocess.DEVNULL, stdout=stdout, stderr=stderr, start_new_session=True
        )
        try:
            process.wait(timeout=timeout)
            outcome = f"exit status {process.returncode}"
        except subprocess.TimeoutExpired:  # the file on disk decides
            outcome = f"no exit within {timeout:g} s"
        finally:
            kill_group(process)
        stderr.seek(0)
        tail = stderr.read()[-1000:].decode(errors="replace")
    return f"{outcome}: {tail}"


def kill_group(process: subprocess.Popen[bytes] | subprocess.Popen[str]) -> None:
    """SIGKILL the process group led by ``process`` and wait until its processes are gone.

    ``process`` must have been started with ``start_new_session=True`` (its pid is its
    group's id). The leader is reaped; the other members, reparented, are waited for by
    polling the group for at most :data:`GROUP_EXIT_TIMEOUT`.
    """
    group = process.pid
    # Once the leader is reaped its pid may be reused: signal the group only while it lives.
    if process.poll() is None or group_alive(group):
        try:
            os.killpg(group, signal.SIGKILL)
        except ProcessLookupError:  # the whole group has just exited
            pass
    try:
        process.wait(timeout=GROUP_EXIT_TIMEOUT)
    except subprocess.TimeoutExpired:  # an unkillable leader (stuck in the kernel): leave it
        return
    deadline = time.monotonic() + GROUP_EXIT_TIMEOUT
    while group_alive(group) and time.monotonic() < deadline:
        time.sleep(0.05)


def group_alive(group: int) -> bool:
    """Whether a process of group ``group`` still runs (zombies, already dead, do not count).

    Reads ``/proc``; without it, asks the kernel (zombies then count until reaped).
    """
    proc = Path("/proc")
    if not proc.is_dir():
        try:
            os.killpg(group, 0)
        except (ProcessLookupError, PermissionError):
            return False
        return True
    for stat in proc.glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rpartition(")")[2].split()
        except OSError:  # the process has just ended
            continue
        if len(fields) > 2 and int(fields[2]) == group and fields[0] not in ("Z", "X"):
            return True
    return False


def remove_tree(path: Path) -> None:
    """Remove the folder ``path``, retrying while late writers still create files in it.

    Gives up silently after :data:`REMOVE_ATTEMPTS` (the folder is a temporary one).
    """
    for _ in range(REMOVE_ATTEMPTS):
        shutil.rmtree(path, ignore_errors=True)
        if not path.exists():
            return
        time.sleep(REMOVE_PAUSE)


def _is_complete_png(path: Path) -> bool:
    """Whether ``path`` holds a PNG file written to its end."""
    return path.is_file() and path.read_bytes().endswith(PNG_END)
