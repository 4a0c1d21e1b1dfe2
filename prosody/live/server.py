"""Frames over a WebSocket, and the page that draws them.

:class:`FrameServer` listens on one address for both: a plain HTTP ``GET /`` gets the page (a drawn face,
the same geometry as ``prosody preview``), and a WebSocket upgrade on any path joins the stream. Each
client gets:

- every frame of the command's own input, as ``{"type": "frame", "source": "input", "frame", "time_s",
  "faps"}`` text messages;
- if it sends audio of its own (the page's microphone button), frames of that audio, ``"source": "client"``,
  to it alone. It first sends ``{"type": "start", "sample_rate": HZ, "encoding": "f32le"|"s16le"}`` and then
  binary messages of mono samples; ``{"type": "stop"}`` flushes its last frames;
- the sound of the command's input, if it asks with ``{"type": "audio", "on": true}`` (``false`` stops it):
  binary messages of about 0.1 s each, a 12-byte little-endian header (float64 start time in s, uint32
  sample rate in Hz) then the mono samples as int16 little-endian, so that a page can play the sound in step
  with the frames;
- the expressivity controls of what it is shown, and a way to change them: on joining it gets
  ``{"type": "expressivity", "source": "input" | "client", "controls": {"activation": 1.0, ...}}``, and it may
  send ``{"type": "expressivity", "activation": 0.5, ...}`` (any of the six controls of
  :class:`~prosody.motion.expressivity.Expressivity`; the others keep their values). They change its own
  audio's frames once it has started sending audio, else the command's input, for every client (each is sent
  the new controls), from the next frame on. A server without an input of its own (``on_expressivity`` None)
  changes the client's own audio only.

A client that stops reading has its oldest frames dropped (it is told once, on stderr), a client that sends
what is not audio is told why and its message ignored, and a client that goes away is reported once: the
server keeps serving the others throughout.

Only the server's own page may open the WebSocket: a browser names the page that opens a WebSocket in its
``Origin`` header, and a page from any other site (which could otherwise watch the stream, or send the
user's microphone) is refused with 403 and one line on the report. The page's own origin is
``http://HOST:PORT`` where HOST is an address (``127.0.0.1``, ``[::1]``, the listening address), ``localhost``
or this machine's name: a name that some other site's DNS could point at this machine is not trusted, which
closes DNS rebinding. More origins are allowed by name (``--allow-origin``). Clients that are not browsers
send no ``Origin`` and are served.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import socket
import struct
import threading
from collections.abc import Callable, Iterable
from importlib import resources
from typing import Any

import numpy as np

from audio_features.errors import VisualProsodyError
from audio_features.pcm import PcmDecoder, PcmFormat

from ..errors import ConfigError
from ..motion.expressivity import RANGES, Expressivity
from ..net import SAFE_HEADERS, OriginPolicy
from .converter import LiveConverter, LiveFrame

#: Frames kept for a client that is not reading (10 s at 30 fps); older ones are dropped.
CLIENT_QUEUE_FRAMES = 300
#: Kernel send buffer of each connection (about 200 frames).
SEND_BUFFER_BYTES = 16 << 10
#: Largest message a client may send (1 MiB: over 5 s of 48 kHz float audio).
MAX_MESSAGE_BYTES = 1 << 20
#: Longest wait for a client's closing handshake when the server closes, in s.
CLOSE_TIMEOUT_S = 1.0
#: The input's sound is sent to the clients that ask for it in pieces of about this length, in s.
AUDIO_PIECE_S = 0.1
#: Header of each piece of sound: start time (s, float64) and sample rate (Hz, uint32), little-endian.
AUDIO_HEADER = struct.Struct("<dI")


class ServerClosedError(ConfigError, RuntimeError):
    """Frames published to a server that has been closed."""


def page_html() -> bytes:
    """The page served at ``/``."""
    return resources.files("prosody.live").joinpath("face.html").read_bytes()


def frame_message(frame: LiveFrame, source: str) -> str:
    return json.dumps({"type": "frame", "source": source, "frame": frame.frame, "time_s": round(frame.time_s, 6),
                       "faps": {str(fap): round(value, 3) for fap, value in frame.faps.items()}},
                      separators=(",", ":"))


def _controls_message(source: str, controls: Expressivity) -> str:
    return json.dumps({"type": "expressivity", "source": source, "controls": controls.as_dict(),
                       "ranges": {name: list(bounds) for name, bounds in RANGES.items()}}, separators=(",", ":"))


class _Client:
    def __init__(self, name: str) -> None:
        self.name = name
        self.queue: asyncio.Queue[str | bytes] = asyncio.Queue(maxsize=CLIENT_QUEUE_FRAMES)
        self.wants_audio = False  # the input's sound, as binary messages
        self.told: set[str] = set()  # problems already reported for this client
        self.converter: LiveConverter | None = None
        self.decoder: PcmDecoder | None = None
        self.expressivity = Expressivity()  # of the client's own audio
        self.transport: asyncio.Transport | None = None  # its connection, to drop it when closing


class FrameServer:
    """Serve frames and the page on ``host:port`` from a background thread.

    Parameters
    ----------
    host, port
        Address to listen on (port 0: any free port; :attr:`port` says which).
    make_converter : callable
        ``make_converter(sample_rate_hz)`` -> a :class:`LiveConverter` for a client's own audio.
    report : callable
        Called with one line for each event worth telling (a client joining or leaving, each problem once).
    allow_origins : iterable of str
        Web origins besides the server's own page allowed to open the WebSocket (``http://host:port``).
    expressivity : Expressivity, optional
        The controls the command started with: of its input, and of each client's own audio until it changes them.
    on_expressivity : callable, optional
        ``on_expressivity(controls)``, called from the server's thread when a client changes the controls of the
        command's input (None: the server has no input of its own). The caller applies them to its converter.
    """

    def __init__(self, host: str, port: int, *, make_converter: Callable[[int], LiveConverter],
                 report: Callable[[str], None], allow_origins: Iterable[str] = (),
                 expressivity: Expressivity | None = None,
                 on_expressivity: Callable[[Expressivity], None] | None = None, face: Any = None) -> None:
        self.host, self.port = host, port
        self.make_converter = make_converter
        self.report = report
        self.origins = OriginPolicy(allow_origins)
        self.expressivity = expressivity or Expressivity()  # of the command's input
        self.on_expressivity = on_expressivity
        self._face = face  # a PhotoHead: the page shows that person's head (its model made on the first request)
        self._face_files: dict[str, tuple[bytes, str]] | None = None
        self._closed = False
        self._clients: set[_Client] = set()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._thread: threading.Thread | None = None
        self._started = threading.Event()
        self._error: BaseException | None = None
        self._page = page_html()
        self.clients_served = 0
        self.audio_messages = 0
        self._sound: list[np.ndarray] = []  # the input's sound not yet sent, and where it starts
        self._sound_start = 0
        self._sound_sent = 0
        self._sound_rate = 0
        self.first_client = threading.Event()  # set when the first client joins

    # lifecycle ------------------------------------------------------------------------------------------
    def start(self) -> FrameServer:
        """Listen; returns once the address is bound (raises OSError if it cannot be)."""
        self._thread = threading.Thread(target=self._run, name="prosody-server", daemon=True)
        self._thread.start()
        self._started.wait()
        if self._error is not None:
            raise self._error
        return self

    def close(self, *, drain_s: float = 1.0) -> None:
        """Send what is queued (for up to ``drain_s``), close every connection and stop listening.

        Returns when the server's thread has ended: about ``drain_s`` plus :data:`CLOSE_TIMEOUT_S`, however its
        clients behave (at most 5 s more on a loaded machine, after which it says so). Later :meth:`publish`
        calls raise :class:`ServerClosedError`.
        """
        self._closed = True
        if self._loop is None or self._stop is None or self._thread is None or not self._thread.is_alive():
            return

        # every page is told the stream has ended, before its connection closes
        with contextlib.suppress(RuntimeError):  # the loop has already ended
            self._loop.call_soon_threadsafe(self._enqueue_all, [*self._sound_pieces(flush=True),
                                                                json.dumps({"type": "end"})])

        async def drained() -> None:
            deadline = asyncio.get_running_loop().time() + drain_s
            while any(not c.queue.empty() for c in self._clients) and asyncio.get_running_loop().time() < deadline:
                await asyncio.sleep(0.02)
            assert self._stop is not None
            self._stop.set()

        with contextlib.suppress(RuntimeError):  # the loop has already ended
            asyncio.run_coroutine_threadsafe(drained(), self._loop)
        self._thread.join(timeout=drain_s + CLOSE_TIMEOUT_S + 5.0)
        if self._thread.is_alive():
            self.report("the server did not stop in time; its connections are dropped with the process")

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/"

    def _run(self) -> None:
        try:
            asyncio.run(self._main())
        except BaseException as error:  # noqa: BLE001 - handed to the starting thread
            self._error = error
            self._started.set()

    async def _main(self) -> None:
        from websockets.asyncio.server import serve

        self._loop = asyncio.get_running_loop()
        self._stop = asyncio.Event()
        async with serve(self._handle, self.host, self.port, process_request=self._http,
                         max_size=MAX_MESSAGE_BYTES, compression=None, close_timeout=CLOSE_TIMEOUT_S) as server:
            self.port = server.sockets[0].getsockname()[1]
            self._started.set()
            await self._stop.wait()
            # a client that never answers the closing handshake is dropped after CLOSE_TIMEOUT_S
            server.close(close_connections=True)
            try:
                await asyncio.wait_for(server.wait_closed(), CLOSE_TIMEOUT_S + 0.5)
            except asyncio.TimeoutError:  # TimeoutError's own name only from Python 3.11
                # a connection in its closing handshake has left server.connections: drop every client's
                for transport in [c.transport for c in self._clients] + [c.transport for c in server.connections]:
                    if transport is not None:
                        transport.abort()

    # frames of the command's input ----------------------------------------------------------------------
    def publish(self, frames: list[LiveFrame]) -> None:
        """Send frames of the command's input to every client (callable from any thread)."""
        if self._closed:
            raise ServerClosedError("the frame server is closed: start a new one to publish frames")
        if self._loop is None or not frames:
            return
        messages: list[str | bytes] = [frame_message(frame, "input") for frame in frames]
        self._loop.call_soon_threadsafe(self._enqueue_all, messages)

    def publish_audio(self, samples: np.ndarray, sample_rate_hz: int) -> None:
        """The command's input's sound (mono, full scale +-1), sent in pieces to the clients that asked for it
        (callable from any thread, in the order of the sound). :meth:`restart_audio` begins a new timeline."""
        if self._closed:
            raise ServerClosedError("the frame server is closed: start a new one to publish sound")
        self._sound_rate = int(sample_rate_hz)
        self._sound.append(np.asarray(samples, dtype=float).ravel())
        pieces = self._sound_pieces(flush=False)
        if pieces and self._loop is not None:
            self._loop.call_soon_threadsafe(self._enqueue_all, pieces, True)

    def restart_audio(self) -> None:
        """The input starts again (a new pass of ``--loop``): what is pending is sent, and time restarts at 0."""
        pieces = self._sound_pieces(flush=True)
        if pieces and self._loop is not None:
            self._loop.call_soon_threadsafe(self._enqueue_all, pieces, True)
        self._sound_start = self._sound_sent = 0

    def _sound_pieces(self, *, flush: bool) -> list[str | bytes]:
        pending = sum(len(part) for part in self._sound)
        if not pending or (not flush and pending < AUDIO_PIECE_S * self._sound_rate):
            return []
        sound = np.concatenate(self._sound)
        self._sound = []
        pcm = (np.clip(sound, -1.0, 1.0) * 32767).round().astype("<i2")
        header = AUDIO_HEADER.pack(self._sound_sent / self._sound_rate, self._sound_rate)
        self._sound_sent += len(sound)
        return [header + pcm.tobytes()]

    def _enqueue_all(self, messages: list[str | bytes], audio: bool = False) -> None:
        for client in list(self._clients):
            if audio and not client.wants_audio:
                continue
            for message in messages:
                if isinstance(message, bytes) and not client.wants_audio:
                    continue
                self._enqueue(client, message)

    def _enqueue(self, client: _Client, message: str | bytes) -> None:
        if client.queue.full():
            client.queue.get_nowait()  # a stalled reader loses its oldest frames, not the others' frames
            self._tell_once(client, "stalled", f"client {client.name} is not reading; its oldest frames are "
                                               "dropped")
        client.queue.put_nowait(message)

    def _tell_once(self, client: _Client, key: str, line: str) -> None:
        if key not in client.told:
            client.told.add(key)
            self.report(line)

    # connections ----------------------------------------------------------------------------------------
    def _http(self, connection, request):
        from websockets.datastructures import Headers
        from websockets.http11 import Response

        upgrades, hosts = request.headers.get_all("Upgrade"), request.headers.get_all("Host")
        if len(upgrades) > 1 or len(hosts) != 1:
            return connection.respond(400, "bad request: one Host and at most one Upgrade header\n")
        if upgrades and upgrades[0].lower() == "websocket":
            origins = request.headers.get_all("Origin")
            if not origins or (len(origins) == 1 and self.origins.allows(origins[0], hosts[0])):
                return None  # go on with the WebSocket handshake
            origin = ", ".join(origins)
            self.report(f"refused a WebSocket from the page at {origin[:200]!r}: only this server's own page may "
                        "connect (allow another with --allow-origin ORIGIN)")
            return connection.respond(403, "forbidden: this stream is only for the page served here\n")
        if not self.origins.serves_host(hosts[0]):
            # DNS rebinding: a page of another site, its name pointed at this machine, reads nothing here
            return connection.respond(421, "misdirected request: this server answers to its own address\n")
        path = request.path.split("?", 1)[0]
        from ..head.web import head_script, model_json  # the head's model is built on the first request

        served = {"/": (lambda: self._page, "text/html; charset=utf-8"),
                  "/index.html": (lambda: self._page, "text/html; charset=utf-8"),
                  "/head.js": (head_script, "text/javascript; charset=utf-8"),
                  "/head.json": (model_json, "application/json")}
        if self._face is not None:
            served.update({name: (lambda body=body: body, kind) for name, (body, kind) in self._face_model().items()})
        if path in served:
            make, kind = served[path]
            body = make()
            # the page and its files: never framed by another site, never sniffed as another type, scripts and
            # connections only from here (the stream at ws(s)://this host; the microphone's worklet is a blob)
            own = hosts[0]
            headers = Headers([("Content-Type", kind), ("Content-Length", str(len(body))), *SAFE_HEADERS.items(),
                               ("Content-Security-Policy",
                                "default-src 'self'; script-src 'self' 'unsafe-inline' blob:; style-src 'self' "
                                f"'unsafe-inline'; img-src 'self' data:; connect-src 'self' ws://{own} wss://{own}; "
                                "frame-ancestors 'none'")])
            return Response(200, "OK", headers, body)
        return connection.respond(404, "not found: the page is at /\n")

    def _face_model(self) -> dict[str, tuple[bytes, str]]:
        """The photo head's model and images, made once (the first page that asks waits for them)."""
        if self._face_files is None:
            from ..head.web import photo_images, photo_model_document

            model = json.dumps(photo_model_document(self._face), separators=(",", ":")).encode("utf-8")
            self._face_files = {"/head.json": (model, "application/json"),
                                **photo_images(self._face)}
        return self._face_files

    async def _handle(self, websocket) -> None:
        from websockets.exceptions import ConnectionClosed

        address = websocket.remote_address
        client = _Client(f"{address[0]}:{address[1]}" if address else "?")
        sock = websocket.transport.get_extra_info("socket")
        if sock is not None:
            # frames are stale after a few seconds: the kernel holds a few seconds of them, not megabytes
            with contextlib.suppress(OSError):
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SEND_BUFFER_BYTES)
        client.expressivity = self.expressivity
        client.transport = websocket.transport
        self._clients.add(client)
        self.clients_served += 1
        self.first_client.set()
        self.report(f"client {client.name} connected ({len(self._clients)} connected)")
        self._enqueue(client, _controls_message("input" if self.on_expressivity else "client", self.expressivity))
        sender = asyncio.create_task(self._send(websocket, client))
        try:
            async for message in websocket:
                await self._receive(websocket, client, message)
        except ConnectionClosed:
            pass
        finally:
            self._clients.discard(client)
            sender.cancel()
            self.report(f"client {client.name} disconnected ({len(self._clients)} connected)")

    async def _send(self, websocket, client: _Client) -> None:
        from websockets.exceptions import ConnectionClosed

        try:
            while True:
                await websocket.send(await client.queue.get())
        except ConnectionClosed:
            pass

    async def _receive(self, websocket, client: _Client, message: str | bytes) -> None:
        loop = asyncio.get_running_loop()
        if isinstance(message, str):
            try:
                request = json.loads(message)
                kind = request["type"]
            except (ValueError, KeyError, TypeError, RecursionError):  # RecursionError: JSON nested too deeply
                await self._refuse(websocket, client, "text", "a text message must be JSON with a \"type\" "
                                                              "(start, stop, audio or expressivity)")
                return
            if kind == "start":
                try:
                    pcm = PcmFormat(int(request.get("sample_rate", 0)), str(request.get("encoding", "f32le")))
                    converter = await loop.run_in_executor(None, self.make_converter, pcm.sample_rate_hz)
                    converter.set_expressivity(client.expressivity)
                    client.converter, client.decoder = converter, PcmDecoder(pcm)
                except (VisualProsodyError, ValueError, TypeError, OverflowError) as error:  # 1e400: infinity
                    await self._refuse(websocket, client, "start", f"cannot start: {error}")
                    return
                self.report(f"client {client.name} is sending audio ({pcm.sample_rate_hz} Hz {pcm.encoding})")
            elif kind == "stop":
                if client.converter is None:
                    await self._refuse(websocket, client, "stop", "stop: no audio was started (send start first)")
                    return
                converter, client.converter = client.converter, None
                frames = await loop.run_in_executor(None, converter.finish)
                for frame in frames:
                    self._enqueue(client, frame_message(frame, "client"))
            elif kind == "expressivity":
                await self._change_expressivity(websocket, client, request)
            elif kind == "audio":
                client.wants_audio = request.get("on") is True
            else:
                await self._refuse(websocket, client, "type", f"unknown message type {kind!r} (start, stop, "
                                                              "audio or expressivity)")
            return
        if client.converter is None or client.decoder is None:
            await self._refuse(websocket, client, "early", "audio before a start message is ignored")
            return
        self.audio_messages += 1
        converter, decoder = client.converter, client.decoder
        try:
            samples = decoder.decode(message)
            frames = await loop.run_in_executor(None, converter.push, samples)
        except VisualProsodyError as error:
            client.converter = None  # its audio is broken: start again to go on
            await self._refuse(websocket, client, "audio", f"audio refused ({error}); send a new start message")
            return
        for frame in frames:
            self._enqueue(client, frame_message(frame, "client"))

    async def _change_expressivity(self, websocket, client: _Client, request: dict) -> None:
        """New controls for the client's own audio once it sends some, else for the command's input."""
        own = client.converter is not None or self.on_expressivity is None
        current = client.expressivity if own else self.expressivity
        changes = {name: value for name, value in request.items() if name != "type"}
        try:
            controls = current.with_changes(**changes)
        except (ConfigError, TypeError) as error:
            await self._refuse(websocket, client, "expressivity", f"expressivity refused: {error}")
            return
        if own:
            client.expressivity = controls
            if client.converter is not None:  # no push of this client's runs meanwhile: its messages come in turn
                client.converter.set_expressivity(controls)
            self._enqueue(client, _controls_message("client", controls))
            return
        assert self.on_expressivity is not None
        self.expressivity = controls
        self.on_expressivity(controls)
        for other in self._clients:  # a page that turns its microphone on later starts from what it was shown
            if other.converter is None:
                other.expressivity = controls
        changed = ", ".join(f"{name} {value:g}" for name, value in controls.as_dict().items()
                            if value != current.as_dict()[name]) or "nothing changed"
        self.report(f"client {client.name} set the input's expressivity: {changed}")
        self._enqueue_all([_controls_message("input", controls)])

    async def _refuse(self, websocket, client: _Client, key: str, problem: str) -> None:
        self._tell_once(client, key, f"client {client.name}: {problem}")
        self._enqueue(client, json.dumps({"type": "error", "message": problem}))

