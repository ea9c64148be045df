"""meshcat's server (zmq requests -> websocket browsers) with two fixes; run as a subprocess.

``python -m ucontrol.viz.meshcat_bridge`` prints ``zmq_url=...`` and ``web_url=...`` and
serves until killed. It is meshcat 0.3's ``ZMQWebSocketBridge`` except that

- the reply to ``wait`` goes through the zmq stream: sent on the raw socket from a timer, it
  left the stream deaf to the next request, so the client hung after ``Visualizer.wait()``;
- a browser that closes while commands are forwarded to it is dropped instead of raising,
  which left the command without reply and the client hung.
"""

from __future__ import annotations

from meshcat.servers.zmqserver import ZMQWebSocketBridge
from tornado.websocket import WebSocketClosedError


class MeshcatBridge(ZMQWebSocketBridge):  # type: ignore[misc]
    """meshcat's zmq-to-websocket bridge, safe with ``wait`` and with closing browsers."""

    def wait_for_websockets(self) -> None:
        """Reply to ``wait`` once a browser is connected."""
        if self.websocket_pool:
            self.zmq_stream.send(b"ok")
        else:
            self.ioloop.call_later(0.1, self.wait_for_websockets)

    def forward_to_websockets(self, frames: list[bytes]) -> None:
        """Send a command to every connected browser, dropping the closed ones."""
        _, _, data = frames
        for websocket in list(self.websocket_pool):
            try:
                websocket.write_message(data, binary=True)
            except WebSocketClosedError:
                self.websocket_pool.discard(websocket)


def main() -> None:
    """Start the bridge on free localhost ports, print its addresses and serve."""
    bridge = MeshcatBridge()
    print(f"zmq_url={bridge.zmq_url}", flush=True)
    print(f"web_url={bridge.web_url}", flush=True)
    bridge.run()


if __name__ == "__main__":
    main()
