"""A meshcat server on localhost, started in a subprocess, and the client connected to it."""

from __future__ import annotations

import atexit
import contextlib
import io
import os
import signal
import subprocess
import sys
import tempfile
import threading
from types import TracebackType

import meshcat

from ucontrol.exceptions import ViewerError
from ucontrol.viz.browser_screenshot import kill_group

#: Longest wait for the server to print its addresses, in [s].
START_TIMEOUT = 30.0
#: The server's program: the bridge, plus a thread that ends the process when its standard
#: input closes, i.e. when the process that started it exits, even killed (SIGKILL runs no
#: ``atexit``), so that no server outlives its client.
_LAUNCHER = """\
import os, runpy, sys, threading
def _watch_parent():
    sys.stdin.buffer.read()  # returns at end of file: the parent has gone
    os._exit(0)
threading.Thread(target=_watch_parent, daemon=True).start()
runpy.run_module("ucontrol.viz.meshcat_bridge", run_name="__main__", alter_sys=True)
"""


class MeshcatServer:
    """Start a meshcat server (zmq + web server on 127.0.0.1) and connect a viewer to it.

    The server is :mod:`ucontrol.viz.meshcat_bridge` (meshcat's own, with two fixes) in a
    subprocess; it runs until :meth:`close`, the end of a ``with`` block or the end of the
    process (however it ends: the server watches its standard input, a pipe from this
    process). It runs in a process group of its own, killed as a whole. Browsers open
    :attr:`url`; the server sends them the current scene when they connect. Its ports are the
    first free ones from 6000 (zmq) and 7000 (web).

    Attributes:
        viewer: The meshcat client (``meshcat.Visualizer``) drawing in the server's scene.
        url: Address of the viewer page, e.g. ``http://127.0.0.1:7000/static/``.

    Raises:
        ViewerError: The server did not start.
    """

    def __init__(self) -> None:
        self._errors = tempfile.TemporaryFile(mode="w+")
        self._process = subprocess.Popen(
            [sys.executable, "-u", "-c", _LAUNCHER],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self._errors,
            text=True,
            start_new_session=True,  # Ctrl-C in a terminal stops the client, close() the server
        )
        atexit.register(self.close)
        try:
            addresses = self._addresses()
        except BaseException:
            self.close()
            raise
        # Drain what the server prints later, so that it never blocks on a full pipe.
        threading.Thread(target=self._process.stdout.read, daemon=True).start()  # type: ignore[union-attr]
        with contextlib.redirect_stdout(io.StringIO()):  # meshcat prints the URL itself
            self.viewer = meshcat.Visualizer(zmq_url=addresses["zmq_url"])
        self.url: str = addresses["web_url"]

    def _addresses(self) -> dict[str, str]:
        """The ``zmq_url`` and ``web_url`` lines the server prints when it listens."""
        addresses: dict[str, str] = {}
        timer = threading.Timer(START_TIMEOUT, self._kill_group)
        timer.start()
        try:
            while len(addresses) < 2:
                line = self._process.stdout.readline()  # type: ignore[union-attr]
                if not line:
                    self._errors.seek(0)
                    raise ViewerError(f"the meshcat server stopped: {self._errors.read()[-2000:]}")
                key, _, value = line.strip().partition("=")
                if key in ("zmq_url", "web_url"):
                    addresses[key] = value
        finally:
            timer.cancel()
        return addresses

    def wait_for_browser(self) -> None:
        """Block until a browser has the viewer page open."""
        self.viewer.wait()

    def static_html(self) -> str:
        """The current scene (and animation) as one HTML page that needs no server.

        The page embeds meshcat's viewer, three.js included, so it opens offline.
        """
        html: str = self.viewer.static_html()
        return html

    def _kill_group(self) -> None:
        """SIGKILL the server's process group (a read of its output then ends)."""
        with contextlib.suppress(ProcessLookupError):
            os.killpg(self._process.pid, signal.SIGKILL)

    def close(self) -> None:
        """Stop the server and every process of its group, and wait until they are gone."""
        atexit.unregister(self.close)
        if self._process.stdin is not None and not self._process.stdin.closed:
            with contextlib.suppress(OSError):
                self._process.stdin.close()
        kill_group(self._process)
        if not self._errors.closed:
            self._errors.close()

    def __enter__(self) -> MeshcatServer:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()
