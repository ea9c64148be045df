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
#: Longest wait for one browser launch, in [s]; a launch that overruns it is killed.
TIMEOUT = 60.0
#: Browser launches tried per screenshot: headless Chromium intermittently never ends its
#: virtual-time budget, or writes the screenshot and then never exits. The last launch runs in
#: real time instead (``--timeout``), which Chromium always ends.
ATTEMPTS = 3
#: Real time a real-time launch gives the page beyond the virtual time asked, in [ms].
REAL_TIME_MARGIN_MS = 3000
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
    errors = []
    for attempt in range(ATTEMPTS):
        out.unlink(missing_ok=True)
        if attempt < ATTEMPTS - 1:
            clock = f"--virtual-time-budget={virtual_time_ms}"
        else:  # the page plays for at least as long, in real time
            clock = f"--timeout={virtual_time_ms + REAL_TIME_MARGIN_MS}"
        with tempfile.TemporaryDirectory() as profile:
            flags = [
                *CHROMIUM_FLAGS,
                f"--user-data-dir={profile}",
                f"--window-size={width},{height}",
            ]
            if offline:
                flags += ["--proxy-server=127.0.0.1:9", "--proxy-bypass-list=<-loopback>"]
            command = [
                executable,
                *flags,
                clock,
                f"--screenshot={out}",
                url,
            ]
            try:
                completed = subprocess.run(command, capture_output=True, text=True, timeout=TIMEOUT)
                errors.append(f"exit status {completed.returncode}: {completed.stderr[-1000:]}")
            except subprocess.TimeoutExpired:  # the file on disk decides
                errors.append(f"no exit within {TIMEOUT:g} s")
        if _is_complete_png(out):
            return out
    raise ViewerError(f"chromium failed {ATTEMPTS} times on {url}; last: {errors[-1]}")


def _is_complete_png(path: Path) -> bool:
    """Whether ``path`` holds a PNG file written to its end."""
    return path.is_file() and path.read_bytes().endswith(PNG_END)
