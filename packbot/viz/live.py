"""The live viewer: meshcat's server in a background thread, listening on 127.0.0.1 only.

meshcat's bridge binds its web server to every interface whatever its ``host``; ours binds the
loopback address itself and reports the port the socket really has (the operating system
wraps a port above 65535 modulo 65536, and 0 means any free port: meshcat would print the port
asked for). :func:`start_viewer` returns a :class:`LiveViewer`.
"""

from __future__ import annotations

import asyncio
import logging
import threading
import webbrowser
from collections.abc import Sequence
from typing import Any

import meshcat
import numpy as np
import tornado.httpserver
import tornado.netutil
import tornado.web
from meshcat.servers.zmqserver import (
    VIEWER_ROOT,
    StaticFileHandlerNoCache,
    WebSocketHandler,
    ZMQWebSocketBridge,
)
from meshcat.visualizer import ViewerWindow
from numpy.typing import NDArray

from packbot.environment import Environment
from packbot.errors import ConfigurationError, PackbotError
from packbot.keywords import checked_arguments
from packbot.model import Robot
from packbot.result import SimResult
from packbot.viz.keyframes import _check_speed
from packbot.viz.scene import _Scene

__all__ = ["LOOPBACK", "LiveViewer", "start_viewer"]

log = logging.getLogger(__name__)

#: The only address the live viewer listens on.
LOOPBACK = "127.0.0.1"


class _LoopbackApplication(tornado.web.Application):
    """A tornado application whose ``listen`` binds the loopback address only.

    Attributes:
        server: The HTTP server, once listening.
        port: The TCP port its socket is bound to (read back from the socket).
    """

    server: Any = None
    port: int | None = None

    def listen(self, port: int, address: str | None = None, **kwargs: Any) -> Any:
        """Listen on ``LOOPBACK``:port, whatever address is asked for."""
        sockets = tornado.netutil.bind_sockets(port, address=LOOPBACK)
        server = tornado.httpserver.HTTPServer(self, **kwargs)
        server.add_sockets(sockets)
        self.server = server
        self.port = int(sockets[0].getsockname()[1])
        return server


class _QuietWebSocketHandler(WebSocketHandler):
    """meshcat's websocket handler, logging instead of printing."""

    def open(self) -> None:
        self.bridge.websocket_pool.add(self)
        log.info("browser connected to the viewer")
        self.bridge.send_scene(self)

    def on_close(self) -> None:
        self.bridge.websocket_pool.discard(self)
        log.info("browser disconnected from the viewer")


def _log_request(handler: tornado.web.RequestHandler) -> None:
    log.debug("%d %s", handler.get_status(), handler.request.uri)


class _LoopbackBridge(ZMQWebSocketBridge):
    """meshcat's ZMQ-to-websocket bridge, serving on 127.0.0.1 only.

    Its ZMQ socket binds ``tcp://{host}:port``, with host 127.0.0.1 already.
    """

    def make_app(self) -> _LoopbackApplication:
        return _LoopbackApplication(
            [
                (
                    r"/static/(.*)",
                    StaticFileHandlerNoCache,
                    {"path": VIEWER_ROOT, "default_filename": "index.html"},
                ),
                (r"/", _QuietWebSocketHandler, {"bridge": self}),
            ],
            log_function=_log_request,
        )


class _Window(ViewerWindow):
    """meshcat's ZMQ client window for a bridge already running (prints nothing)."""

    def __init__(self, zmq_url: str, web_url: str) -> None:
        self.server_proc = None
        self.zmq_url = zmq_url
        self.web_url = web_url
        self.connect_zmq()

    def close(self) -> None:
        self.zmq_socket.close(linger=0)


def _check_port(port: object) -> int | None:
    """A TCP port: None (the first free one from 7000), or an integer in 1..65535."""
    if port is None:
        return None
    if isinstance(port, (bool, np.bool_)) or not isinstance(port, (int, np.integer)):
        raise ConfigurationError("port", port, "None or an integer TCP port in 1..65535")
    if not 1 <= int(port) <= 65535:
        raise ConfigurationError("port", port, "None or an integer TCP port in 1..65535")
    return int(port)


@checked_arguments
class LiveViewer:
    """A meshcat viewer served on 127.0.0.1, its server running in a background thread.

    Use :func:`start_viewer` to make one; close it (or use it as a context manager) to stop
    the server. A browser that connects late receives the whole scene, animation included.

    Attributes:
        url: The page to open, ``http://127.0.0.1:PORT/static/``.
        port: The web server's TCP port.
        zmq_url: The bridge's ZMQ endpoint (``tcp://127.0.0.1:...``).
    """

    def __init__(
        self,
        robot: Robot,
        *,
        environment: Environment | None = None,
        port: int | None = None,
        collision: bool = False,
    ) -> None:
        port = _check_port(port)
        self._bridge: _LoopbackBridge | None = None
        self._error: BaseException | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        ready = threading.Event()
        self._thread = threading.Thread(
            target=self._serve, args=(port, ready), name="packbot-meshcat", daemon=True
        )
        self._thread.start()
        ready.wait(30.0)
        if self._error is not None or self._bridge is None:
            self._thread.join(5.0)
            if isinstance(self._error, OSError):
                raise ConfigurationError(
                    "port", port, f"a free TCP port on {LOOPBACK} ({self._error})"
                ) from self._error
            raise PackbotError(f"the meshcat server did not start: {self._error!r}")
        bridge = self._bridge
        port_bound = bridge.app.port
        assert port_bound is not None
        # meshcat reports the port it asked for; the socket's is the one to open
        bridge.fileserver_port = port_bound
        bridge.web_url = f"http://{LOOPBACK}:{port_bound}/static/"
        self.port: int = port_bound
        self.zmq_url: str = str(bridge.zmq_url)
        self.url: str = str(bridge.web_url)
        self._window: _Window = _Window(self.zmq_url, self.url)
        self.viewer: meshcat.Visualizer = meshcat.Visualizer(window=self._window)
        self._scene: _Scene = _Scene.load(robot, self.viewer, environment, collision)
        self._robot: Robot = robot
        self.display(robot.pose("drive") if "drive" in robot.poses else np.zeros(robot.nq))

    def _serve(self, port: int | None, ready: threading.Event) -> None:
        loop = asyncio.new_event_loop()
        asyncio.set_event_loop(loop)
        self._loop = loop

        async def make() -> _LoopbackBridge:
            return _LoopbackBridge(host=LOOPBACK, port=port)

        try:
            self._bridge = loop.run_until_complete(make())
        except BaseException as exc:  # reported to the caller's thread
            self._error = exc
            ready.set()
            loop.close()
            return
        ready.set()
        bridge = self._bridge
        try:
            loop.run_forever()
        finally:
            bridge.app.server.stop()
            for ws in list(bridge.websocket_pool):
                ws.close()
            bridge.zmq_stream.close()
            bridge.zmq_socket.close(linger=0)
            loop.run_until_complete(asyncio.sleep(0))
            loop.close()

    def display(self, q: Sequence[float] | NDArray[np.float64]) -> None:
        """Show the robot at configuration q [rad] (shape (nq,))."""
        q = np.asarray(q, dtype=float)
        if q.shape != (self._robot.nq,):
            raise ConfigurationError("q", q.shape, f"shape ({self._robot.nq},)")
        self._scene.place(q)

    def play(self, result: SimResult, speed: float = 1.0) -> None:
        """Send a result as an animation clip; connected browsers play it at once.

        Args:
            result: The simulation result.
            speed: Playback rate: 1 is real time, 0.25 four times slower [-].
        """
        speed = _check_speed(speed)
        self.display(result.q[0])
        anim = self._scene.animation(result, speed)
        self.viewer.set_animation(anim, play=True, repetitions=1)

    def open(self) -> None:
        """Open the viewer's page in the default web browser."""
        webbrowser.open(self.url, new=2)

    def close(self) -> None:
        """Stop the server and release its ports (idempotent)."""
        if self._thread.is_alive() and self._loop is not None:
            self._window.close()
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join(10.0)

    def __enter__(self) -> LiveViewer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@checked_arguments
def start_viewer(
    robot: Robot,
    *,
    environment: Environment | None = None,
    port: int | None = None,
    open_browser: bool = False,
    collision: bool = False,
) -> LiveViewer:
    """Start a live meshcat viewer listening on 127.0.0.1 only, showing the robot.

    Args:
        robot: The robot to show (drawn in its ``drive`` pose).
        environment: The obstacles; None means the floor alone.
        port: The web server's TCP port (1..65535); None takes the first free one from 7000.
        open_browser: Open the page in the default browser.
        collision: Show the convex collision pieces instead of the visual meshes.

    Returns:
        The running viewer; its ``url`` is the page to open.

    Raises:
        ConfigurationError: The port is out of range or taken.
    """
    viewer = LiveViewer(robot, environment=environment, port=port, collision=collision)
    if open_browser:
        viewer.open()
    return viewer
