"""Screenshots of viewer pages in headless Chromium (Debian's ``chromium``), for tests and docs."""

from __future__ import annotations

import shutil
import subprocess
import tempfile
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
#: Longest run of the browser for one screenshot, in [s].
TIMEOUT = 180.0


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

    Returns:
        The path written.

    Raises:
        ViewerError: chromium is not installed, or failed.
    """
    executable = find_chromium()
    if executable is None:
        raise ViewerError("chromium is not installed (Debian: apt-get install -y chromium)")
    out = Path(out).resolve()
    with tempfile.TemporaryDirectory() as profile:
        flags = [*CHROMIUM_FLAGS, f"--user-data-dir={profile}", f"--window-size={width},{height}"]
        if offline:
            flags += ["--proxy-server=127.0.0.1:9", "--proxy-bypass-list=<-loopback>"]
        command = [
            executable,
            *flags,
            f"--virtual-time-budget={virtual_time_ms}",
            f"--screenshot={out}",
            url,
        ]
        completed = subprocess.run(command, capture_output=True, text=True, timeout=TIMEOUT)
    if completed.returncode != 0 or not out.is_file():
        raise ViewerError(f"chromium failed on {url}: {completed.stderr[-2000:]}")
    return out
