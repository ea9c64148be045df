"""A meshcat server on localhost, started in a subprocess, and the client connected to it."""

from __future__ import annotations

import contextlib
import io
from types import TracebackType

import meshcat


class MeshcatServer:
    """Start meshcat's server (zmq + web server on 127.0.0.1) and connect a viewer to it.

    The server runs until :meth:`close` (or the end of a ``with`` block, or of the process).
    Browsers open :attr:`url`; the server sends them the current scene when they connect.

    Attributes:
        viewer: The meshcat client (``meshcat.Visualizer``) drawing in the server's scene.
        url: Address of the viewer page, e.g. ``http://127.0.0.1:7000/static/``.
    """

    def __init__(self) -> None:
        with contextlib.redirect_stdout(io.StringIO()):  # meshcat prints the URL itself
            self.viewer = meshcat.Visualizer()
        self.url: str = self.viewer.url()

    def wait_for_browser(self) -> None:
        """Block until a browser has the viewer page open."""
        self.viewer.wait()

    def static_html(self) -> str:
        """The current scene (and animation) as one HTML page that needs no server.

        The page embeds meshcat's viewer, three.js included, so it opens offline.
        """
        html: str = self.viewer.static_html()
        return html

    def close(self) -> None:
        """Stop the server."""
        process = self.viewer.window.server_proc
        if process is not None and process.poll() is None:
            process.kill()
            process.wait()

    def __enter__(self) -> MeshcatServer:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()
