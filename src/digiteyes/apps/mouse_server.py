"""The 3D mouse in a browser: a local web server that streams mouse states over a WebSocket.

``GET /`` serves the page (``mouse_web/index.html``), ``GET /mouse.js`` its script (both
ship in the package; nothing is fetched from the internet), and ``/ws`` is the WebSocket.
Each frame of a :class:`~digiteyes.apps.mouse_stream.MouseStream` goes out as one JSON
text message (:meth:`MouseFrame.to_message`: pole, buttons, timestamps) followed, when
the frame has one, by the overlay JPEG as a binary message. The page draws the scene of
thesis Fig. 4.9 (ground plane, pole cursor with its shadow, a sphere to pick up) and the
latency from frame to page.

The stream starts when the first page connects (so a bounded replay is seen whole) and
runs in a worker thread; the server binds 127.0.0.1 only and stops on SIGINT/SIGTERM or,
after ``linger_s``, when the stream ends.
"""

from __future__ import annotations

import asyncio
import json
import signal
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import resources

from digiteyes.apps.mouse_stream import MouseFrame, MouseStream
from digiteyes.errors import DigitEyesError

HOST = "127.0.0.1"
"""The server listens on the loopback interface only."""

STATIC_FILES = {"/": ("index.html", "text/html; charset=utf-8"),
                "/index.html": ("index.html", "text/html; charset=utf-8"),
                "/mouse.js": ("mouse.js", "text/javascript; charset=utf-8")}
"""URL path -> (file in ``digiteyes/apps/mouse_web``, content type)."""

DEFAULT_SPHERE = (0.0, 30.0, 15.0)
"""Sphere of the scene: centre x, y on the ground and radius, table mm. It lies 30 mm in
front of the resting pole, so the ``mouse`` scenario's raised finger (pole tip about
35 mm up at the origin) reaches it when the thumb button is pressed (frames 158-192)."""

DEFAULT_REACH_MM = 45.0
"""A button press picks the sphere up when the pole tip is at most this far (mm) from the
sphere's centre."""


class ServerError(DigitEyesError):
    """The mouse server could not start (port in use, missing package)."""


@dataclass
class SceneConfig:
    """What the page needs before the first frame: the sphere, the reach, a title."""

    sphere: tuple[float, float, float] = DEFAULT_SPHERE
    reach_mm: float = DEFAULT_REACH_MM
    description: str = ""
    fps: float = 10.0

    def to_message(self) -> dict:
        return {"type": "hello", "sphere": list(self.sphere), "reach_mm": self.reach_mm,
                "description": self.description, "fps": self.fps}


def static_file(name: str) -> bytes:
    """The bytes of one of the page's files shipped in ``digiteyes/apps/mouse_web``."""
    return resources.files("digiteyes.apps").joinpath("mouse_web", name).read_bytes()


@dataclass
class MouseServer:
    """Serve the mouse page and stream ``stream`` to every connected page.

    Parameters
    ----------
    stream : the frames to send (consumed once, starting when the first page connects).
    port : TCP port on 127.0.0.1 (0: any free port; :attr:`url` says which).
    config : scene settings sent to each page when it connects.
    linger_s : seconds to keep serving after the stream ended (pages read the last state).
    on_frame : called with each frame after it was sent (e.g. to log states).
    """

    stream: MouseStream
    port: int = 8765
    config: SceneConfig = field(default_factory=SceneConfig)
    linger_s: float = 1.0
    on_frame: Callable[[MouseFrame], None] | None = None
    url: str = ""
    frames_sent: int = 0
    _clients: set = field(default_factory=set)
    _stop: threading.Event = field(default_factory=threading.Event)

    def run(self, on_ready: Callable[[str], None] | None = None) -> None:
        """Serve until the stream ends (plus ``linger_s``) or SIGINT/SIGTERM arrives;
        ``on_ready(url)`` is called once the socket listens."""
        try:
            asyncio.run(self._serve(on_ready))
        except KeyboardInterrupt:
            self._stop.set()

    def stop(self) -> None:
        """Ask the server to stop (thread-safe)."""
        self._stop.set()

    async def _serve(self, on_ready: Callable[[str], None] | None) -> None:
        try:
            from websockets.asyncio.server import serve
        except ImportError as exc:
            raise ServerError("digiteyes mouse needs the 'websockets' package: pip install "
                              "'digiteyes[mouse]'") from exc
        loop = asyncio.get_running_loop()
        stopping = asyncio.Event()
        for sig in (signal.SIGINT, signal.SIGTERM):
            try:
                loop.add_signal_handler(sig, stopping.set)
            except (NotImplementedError, RuntimeError, ValueError):
                pass  # not the main thread (e.g. tests): stop() still works
        first_page = asyncio.Event()

        async def handler(connection) -> None:
            await connection.send(json.dumps(self.config.to_message()))
            self._clients.add(connection)
            first_page.set()
            try:
                await connection.wait_closed()
            finally:
                self._clients.discard(connection)

        try:
            server = await serve(handler, HOST, self.port, process_request=_http_files,
                                 max_size=2**16)
        except OSError as exc:
            raise ServerError(f"cannot listen on {HOST}:{self.port}: {exc.strerror}") from exc
        async with server:
            port = server.sockets[0].getsockname()[1]
            self.url = f"http://{HOST}:{port}/"
            if on_ready is not None:
                on_ready(self.url)
            watcher = asyncio.create_task(self._watch_stop(stopping))
            waiter = asyncio.create_task(first_page.wait())
            await asyncio.wait({waiter, asyncio.create_task(stopping.wait())},
                               return_when=asyncio.FIRST_COMPLETED)
            if not stopping.is_set():
                producer = loop.run_in_executor(None, self._produce, loop)
                await asyncio.wait({producer, asyncio.create_task(stopping.wait())},
                                   return_when=asyncio.FIRST_COMPLETED)
                if stopping.is_set():
                    self._stop.set()  # the producer stops after its current frame
                await producer
                if not stopping.is_set():
                    self._broadcast(json.dumps({"type": "end", "frames": self.frames_sent}))
                    try:
                        await asyncio.wait_for(stopping.wait(), self.linger_s)
                    except TimeoutError:
                        pass
            watcher.cancel()
            waiter.cancel()

    async def _watch_stop(self, stopping: asyncio.Event) -> None:
        while not self._stop.is_set():
            await asyncio.sleep(0.05)
        stopping.set()

    def _produce(self, loop: asyncio.AbstractEventLoop) -> None:
        """Worker thread: pull frames from the stream and hand them to the event loop. A
        digiteyes error of the source (no hand found, an unreadable frame) is told to the
        pages as an ``error`` message, then raised to the command."""
        frames = self.stream.frames
        try:
            for frame in frames:
                if self._stop.is_set():
                    break
                text = json.dumps(frame.to_message())
                future = asyncio.run_coroutine_threadsafe(
                    self._send(text, frame.overlay_jpeg), loop)
                future.result()
                self.frames_sent += 1
                if self.on_frame is not None:
                    self.on_frame(frame)
        except DigitEyesError as exc:
            message = json.dumps({"type": "error", "message": str(exc)})
            asyncio.run_coroutine_threadsafe(self._send(message, None), loop).result()
            raise
        finally:
            close = getattr(frames, "close", None)
            if close is not None:
                close()

    async def _send(self, text: str, image: bytes | None) -> None:
        self._broadcast(text)
        if image is not None:
            self._broadcast(image)

    def _broadcast(self, message: str | bytes) -> None:
        from websockets.asyncio.server import broadcast
        broadcast(set(self._clients), message)


def _http_files(connection, request):
    """``process_request`` hook: the page's files over plain HTTP, the socket at ``/ws``."""
    from websockets.datastructures import Headers
    from websockets.http11 import Response

    path = request.path.split("?", 1)[0]
    if path == "/ws":
        return None
    if path not in STATIC_FILES:
        return connection.respond(404, f"no such file: {path}\n")
    name, content_type = STATIC_FILES[path]
    body = static_file(name)
    headers = Headers([("Content-Type", content_type), ("Content-Length", str(len(body))),
                       ("Cache-Control", "no-store"), ("Connection", "close")])
    return Response(200, "OK", headers, body)

