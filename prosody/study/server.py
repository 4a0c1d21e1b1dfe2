"""The study's web page and its answers (``prosody study serve``).

One HTTP server on a loopback address by default. A participant opens ``/`` (the page: everything it needs is
served here, nothing comes from another site), gets an anonymous ID (kept in the browser, and shown so that they
can come back from another one with ``/?participant=ID``), watches each trial and answers; the page saves each
answer before showing the next trial, and retries while the server is away. The routes:

- ``GET /``: the page; ``GET /api/study``: the design, the question and the answer options;
- ``POST /api/participants``: a new participant; ``GET /api/state?participant=ID``: where they are;
- ``POST /api/answer`` ``{"participant", "position", "answer", "seconds"}``: one answer, one transaction;
- ``GET /stimuli/<sha256 prefix>.mp4`` and ``.json``: the videos listed in the stimuli manifest and their head
  frames (and nothing else), named by their content so that the address does not say the condition, with byte
  ranges; ``GET /head.js`` and ``/head.json``: the WebGL head and its model;
- ``GET /admin/export.csv`` and ``/admin/progress`` with the organiser's token (``Authorization: Bearer TOKEN``
  or ``?token=TOKEN``), printed when the server starts.

Limits, so that one client cannot stall or skew the study: at most :data:`MAX_HANDLERS` connections are
served at once (the next wait in a listen queue of :data:`LISTEN_BACKLOG`, then are told 503 with
``Retry-After``); a connection silent for :data:`CONNECTION_TIMEOUT_S` is closed; a connection that fails is told
to the organiser in one line (at most one such line a second); at most :data:`NEW_PER_CLIENT_PER_MINUTE` new
participants a minute come from one address and :data:`NEW_PER_MINUTE` in all (429 with ``Retry-After``), so a
script cannot fill the database or shift the counterbalancing. Videos are read from disk by the range asked for,
and only files inside the stimulus folder (resolved) are served.

Requests from a page of another site are refused: a browser names the page in ``Origin`` (and
``Sec-Fetch-Site``), and only this server's own origin, on a host no other site can point here (an address,
``localhost``, this machine's name), or one allowed with ``--allow-origin`` is served. Answers must be JSON.
"""

from __future__ import annotations

import collections
import contextlib
import functools
import hashlib
import hmac
import json
import os
import re
import secrets
import socket
import sqlite3
import sys
import threading
import time
import urllib.parse
from collections.abc import Callable, Iterable
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from pathlib import Path

from ..errors import ConfigError
from ..net import SAFE_HEADERS, OriginPolicy
from .designs import StudyPlan
from .stimuli import check_stimuli
from .store import StudyStore, StudyStoreError

#: Largest request body read (an answer is under 200 bytes).
MAX_BODY_BYTES = 4096
#: Questions asked, per design.
QUESTIONS = {"paired": "Which face moves more naturally with the voice?",
             "mos": "How natural is the face's motion with the voice?",
             "identification": "What does the face express?"}
_RANGE = re.compile(r"bytes=(\d{0,18})-(\d{0,18})$")
#: Connections served at once; the next ones wait in the listen queue, and past it are told to come back.
MAX_HANDLERS = 64
#: Connections the system holds waiting to be served (50 voters at once must not be reset).
LISTEN_BACKLOG = 256
#: Seconds a connection may stay silent (a half-sent request, a reader that stopped) before it is closed.
CONNECTION_TIMEOUT_S = 20.0
#: New anonymous participants allowed per client address, and in all, within a minute (more: 429, try later).
NEW_PER_CLIENT_PER_MINUTE = 10
NEW_PER_MINUTE = 120
#: Bytes of a video sent at a time.
VIDEO_BLOCK_BYTES = 1 << 16
#: How often the serving loop looks for a shutdown, in s (closing the server waits at most this long).
SHUTDOWN_POLL_S = 0.05


def study_page() -> bytes:
    return resources.files("prosody.study").joinpath("study.html").read_bytes()


#: Largest head-frames file a study serves (a 10-minute stimulus at 30 fps and 30 FAPs is about 5 MB).
MAX_HEAD_FRAMES_BYTES = 64 << 20


def checked_head_frames(folder: Path, motion: object, digest: object, *, seconds: object = None) -> bytes | str:
    """The bytes of a video's head frames (``<condition>.head.json``) if they are what the manifest recorded and
    a page can play them; else why not (a phrase).

    They must be inside the stimuli folder, hash to ``motion_sha256``, and hold the head-frames document:
    its format, a frame rate of 1-1000, FAP numbers 1-68, one row of finite numbers per frame with a value for
    each FAP, and as many frames as the video's ``seconds`` (within two)."""
    if not motion or not digest:
        return "are not in the manifest"
    try:
        path = (folder / str(motion)).resolve(strict=True)
        if not path.is_relative_to(folder) or not path.is_file():
            return "are not a file inside the stimuli folder"
        if path.stat().st_size > MAX_HEAD_FRAMES_BYTES:
            return f"are larger than {MAX_HEAD_FRAMES_BYTES >> 20} MB"
        body = path.read_bytes()
    except (OSError, RuntimeError) as error:
        return f"cannot be read ({getattr(error, 'strerror', None) or error})"
    if hashlib.sha256(body).hexdigest() != str(digest):
        return "changed since the stimuli were made (their SHA-256 is not the manifest's)"
    try:
        _check_head_frames(json.loads(body), seconds)
    except (ValueError, KeyError, TypeError, RecursionError) as error:
        return f"are not head frames a page can play ({error})"
    return body


def _is_number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _check_head_frames(document: dict, seconds: object) -> None:
    """Raise ValueError (or KeyError, TypeError) unless ``document`` is head frames a page can play."""
    from ..head.web import HEAD_FRAMES_FORMAT

    fps, faps, frames = document["fps"], document["faps"], document["frames"]
    if document.get("format") != HEAD_FRAMES_FORMAT:
        raise ValueError(f"format {document.get('format')!r}")
    if not _is_number(fps) or not 1 <= fps <= 1000:
        raise ValueError(f"frame rate {fps!r}")
    if not isinstance(faps, list) or not all(isinstance(f, int) and _is_number(f) and 1 <= f <= 68 for f in faps):
        raise ValueError("FAP numbers")
    if not isinstance(frames, list) or not frames:
        raise ValueError("no frames")
    for row in frames:
        if not isinstance(row, list) or len(row) != len(faps) or not all(
                _is_number(v) and v == v and abs(v) < 1e9 for v in row):
            raise ValueError("a frame that is not one number per FAP")
    if _is_number(seconds) and abs(len(frames) - seconds * fps) > 2:
        raise ValueError(f"{len(frames)} frames for a video of {seconds:g} s")


class StudyServer:
    """Serves ``plan``'s study with the videos of ``stimuli`` and the answers in ``store``.

    Parameters
    ----------
    plan : StudyPlan
    stimuli : folder
        Made by ``prosody study stimuli`` for this plan (checked).
    store : StudyStore
        The database of answers (for this plan).
    host, port : str, int
        Where to listen (port 0: any free port; see :attr:`url`).
    break_every : int
        Trials between two break screens (0: none).
    allow_origins : iterable of str
        Other web origins allowed to use the study (``http://host:port``).
    token : str, optional
        The organiser's token (default: a new random one, :attr:`token`).
    report : callable, optional
        Gets one line per event worth telling the organiser.
    """

    def _head_files(self, manifest: dict) -> dict[str, Callable[[], tuple[bytes, str]]]:
        """What the ballot's WebGL head loads: head.js and the 3D head's model, or, where the stimuli show a
        photo's head (``face`` in the manifest), that head's model and images, made here from the kept photo
        (as the videos were: the same landmarks, the same head)."""
        from ..head.web import head_script, model_json

        files: dict[str, Callable[[], tuple[bytes, str]]] = {
            "/head.js": lambda: (head_script(), "text/javascript; charset=utf-8"),
            "/head.json": lambda: (model_json(), "application/json")}
        face = manifest.get("face")
        if isinstance(face, dict):
            from ..head.photo import photo_head
            from ..head.web import photo_images, photo_model_document

            path = self.folder / str(face.get("file", ""))
            if not path.is_file() or hashlib.sha256(path.read_bytes()).hexdigest() != face.get("sha256"):
                raise ConfigError(f"{path}: the stimuli's photo is missing or changed; run 'prosody study stimuli' "
                                  "again")
            head = photo_head(path)
            model = json.dumps(photo_model_document(head), separators=(",", ":")).encode("utf-8")
            files["/head.json"] = lambda: (model, "application/json")
            images = photo_images(head)
            files.update({name: functools.partial(images.__getitem__, name) for name in images})
        return files

    def __init__(self, plan: StudyPlan, stimuli: str | Path, store: StudyStore, *, host: str = "127.0.0.1",
                 port: int = 8766, break_every: int = 20, allow_origins: Iterable[str] = (),
                 token: str | None = None, report: Callable[[str], None] | None = None) -> None:
        manifest = check_stimuli(plan, stimuli)
        self.plan, self.store = plan, store
        self.report: Callable[[str], None] = report or (lambda line: None)
        self.folder = Path(stimuli).resolve()
        # videos are served by the start of their SHA-256: nothing in the address names the condition
        self.files = {f"{str(entry['sha256'])[:24]}.mp4": self.folder / str(entry["file"])
                      for entry in manifest["videos"].values()}
        self.videos = {key: f"/stimuli/{str(entry['sha256'])[:24]}.mp4" for key, entry in manifest["videos"].items()}
        # the head's frames of each video, checked once and served from memory as checked (manifests made before
        # they were written have none; frames that fail a check leave that video shown as recorded)
        self.motions: dict[str, str | None] = {}
        self.motion_bodies: dict[str, bytes] = {}
        for key, entry in manifest["videos"].items():
            motion, digest = entry.get("motion"), entry.get("motion_sha256")
            checked = checked_head_frames(self.folder, motion, digest, seconds=entry.get("seconds"))
            if isinstance(checked, bytes):
                name = f"{str(digest)[:24]}.json"
                self.motion_bodies[name] = checked
                self.motions[key] = f"/stimuli/{name}"
            else:
                self.motions[key] = None
                if motion:
                    self.report(f"{key}: its head frames {str(motion)!r} {checked}; that video is shown as "
                                "recorded, without the WebGL head")
        self.labels = {name: str(entry.get("label", name)) for name, entry in manifest["conditions"].items()}
        self.head_files = self._head_files(manifest)
        self.break_every = break_every
        self.origins = OriginPolicy(allow_origins)
        self.token = token or secrets.token_urlsafe(18)
        self._page = study_page()
        self.arrivals = _Arrivals()
        self._quiet = _OneLinePerSecond(self.report)
        handler = type("Handler", (_Handler,), {"study": self, "timeout": CONNECTION_TIMEOUT_S})
        server: type[_StudyHTTPServer] = _StudyHTTPServer
        if ":" in host:
            server = type("_StudyHTTPServer6", (_StudyHTTPServer,), {"address_family": socket.AF_INET6})
        try:
            self._http = server((host, port), handler, on_error=self._quiet)
        except (OSError, OverflowError) as error:
            raise ConfigError(f"cannot listen on {host}:{port} ({getattr(error, 'strerror', None) or error})") \
                from None
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        host, port = self._http.server_address[:2]
        name = host.decode() if isinstance(host, bytes) else str(host)
        shown = f"[{name}]" if ":" in name else name
        return f"http://{shown}:{port}/"

    def start(self) -> StudyServer:
        # the loop looks for a shutdown every SHUTDOWN_POLL_S: closing takes no longer than that
        self._thread = threading.Thread(target=self._http.serve_forever, kwargs={"poll_interval": SHUTDOWN_POLL_S},
                                        name="study-server", daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        self._http.shutdown()
        self._http.server_close()
        if self._thread is not None:
            self._thread.join(timeout=5)

    def study_info(self) -> dict:
        design = self.plan.design
        info: dict = {"design": design, "question": QUESTIONS[design], "total": len(self.plan.trials),
                      "break_every": self.break_every, "study": self.plan.sha256[:12]}
        if design == "identification":
            info["options"] = [{"name": name, "label": self.labels.get(name, name)} for name in self.plan.conditions]
        if design == "mos":
            info["options"] = [{"name": str(k), "label": label} for k, label in
                               ((1, "1 bad"), (2, "2 poor"), (3, "3 fair"), (4, "4 good"), (5, "5 excellent"))]
        return info

    def with_videos(self, state: dict) -> dict:
        trial = state.pop("trial", None)
        if trial is not None:
            keys = [f"{trial['stimulus']}/{name}" for name in trial["conditions"]]
            state["trial"] = {"position": trial["position"], "videos": [self.videos[key] for key in keys],
                              "motion": [self.motions[key] for key in keys]}
        return state


class _OneLinePerSecond:
    """Tells the organiser of connections that went wrong (a client gone, a timeout) in one line each, at most
    one a second: a burst is summed up as a count, never a traceback."""

    def __init__(self, report: Callable[[str], None]) -> None:
        self.report, self.lock, self.last, self.held = report, threading.Lock(), 0.0, 0

    def __call__(self, line: str) -> None:
        with self.lock:
            now = time.monotonic()
            if now - self.last < 1.0:
                self.held += 1
                return
            held, self.held, self.last = self.held, 0, now
        self.report(line + (f" (and {held} more since the last such line)" if held else ""))


class _Arrivals:
    """New participants in the last minute, per client address and in all."""

    def __init__(self, per_client: int = NEW_PER_CLIENT_PER_MINUTE, in_all: int = NEW_PER_MINUTE) -> None:
        self.per_client, self.in_all = per_client, in_all
        self.lock = threading.Lock()
        self.times: dict[str, collections.deque] = {}
        self.all: collections.deque = collections.deque()

    def admit(self, client: str) -> str | None:
        """None if ``client`` may become a new participant now (counted), else why not."""
        now = time.monotonic()
        with self.lock:
            for queue in (self.all, *self.times.values()):
                while queue and now - queue[0] > 60.0:
                    queue.popleft()
            self.times = {key: queue for key, queue in self.times.items() if queue}
            mine = self.times.setdefault(client, collections.deque())
            if len(mine) >= self.per_client:
                return f"at most {self.per_client} new participants a minute from one address"
            if len(self.all) >= self.in_all:
                return f"at most {self.in_all} new participants a minute"
            mine.append(now)
            self.all.append(now)
            return None


class _StudyHTTPServer(ThreadingHTTPServer):
    """A thread per connection, at most :data:`MAX_HANDLERS` at once, a deep listen queue, and errors of a
    connection told in one line."""

    request_queue_size = LISTEN_BACKLOG
    daemon_threads = True

    def __init__(self, address, handler, *, on_error: Callable[[str], None]) -> None:
        self.slots = threading.BoundedSemaphore(MAX_HANDLERS)
        self.on_error = on_error
        super().__init__(address, handler)

    def process_request(self, request, client_address) -> None:
        if not self.slots.acquire(timeout=1.0):  # every handler busy: the client is asked to come back
            with contextlib.suppress(OSError):
                request.settimeout(1.0)
                request.sendall(b"HTTP/1.1 503 Service Unavailable\r\nRetry-After: 1\r\nContent-Length: 0\r\n"
                                b"Connection: close\r\n\r\n")
            self.shutdown_request(request)
            self.on_error(f"{MAX_HANDLERS} connections busy: one more was asked to come back")
            return
        try:
            super().process_request(request, client_address)
        except BaseException:
            self.slots.release()
            raise

    def process_request_thread(self, request, client_address) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            self.slots.release()

    def handle_error(self, request, client_address) -> None:
        error = sys.exc_info()[1]
        what = "went away" if isinstance(error, (ConnectionError, BrokenPipeError)) else \
            "was too slow and was closed" if isinstance(error, TimeoutError) else f"failed ({error!r})"
        self.on_error(f"a connection from {client_address[0]} {what}")


class _Handler(BaseHTTPRequestHandler):
    study: StudyServer
    server_version = "prosody-study"
    sys_version = ""

    def log_message(self, format: str, *args: object) -> None:  # noqa: A002 - the base class's name
        pass  # requests are not logged one by one; events are reported

    # helpers ---------------------------------------------------------------------------------------------------
    def _send(self, status: int, body: bytes, content_type: str, extra: dict[str, str] | None = None) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        for key, value in {**SAFE_HEADERS, **(extra or {})}.items():
            self.send_header(key, value)
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _json(self, status: int, payload: dict) -> None:
        self._send(status, json.dumps(payload).encode(), "application/json")

    def _error(self, status: int, message: str) -> None:
        self._json(status, {"error": message})

    def _allowed_origin(self) -> bool:
        """True unless a browser says the request comes from a page of another site, or the request names a host
        another site's DNS could point here (the policy of :class:`prosody.net.OriginPolicy`)."""
        hosts = self.headers.get_all("Host") or []
        origins = self.headers.get_all("Origin") or []
        if self.headers.get("Sec-Fetch-Site", "").lower() == "cross-site" and not origins:
            return False
        if len(hosts) > 1 or len(origins) > 1:
            return False
        policy = self.study.origins
        if hosts and not policy.serves_host(hosts[0]):
            return False  # DNS rebinding
        return policy.allows(origins[0] if origins else None, hosts[0] if hosts else "")

    def _query(self) -> dict[str, str]:
        query = urllib.parse.urlsplit(self.path).query
        return {key: values[0] for key, values in urllib.parse.parse_qs(query).items()}

    def _token_ok(self) -> bool:
        given = self._query().get("token", "")
        header = self.headers.get("Authorization", "")
        if header.startswith("Bearer "):
            given = header[7:].strip()
        return bool(given) and hmac.compare_digest(given.encode(), self.study.token.encode())

    def _body(self) -> dict | None:
        if self.headers.get("Content-Type", "").split(";")[0].strip().lower() != "application/json":
            self._error(415, "send JSON (Content-Type: application/json)")
            return None
        try:
            length = int(self.headers.get("Content-Length", ""))
        except ValueError:
            self._error(411, "a Content-Length is needed")
            return None
        if not 0 <= length <= MAX_BODY_BYTES:
            self._error(413, f"the request is over {MAX_BODY_BYTES} bytes")
            return None
        try:
            payload = json.loads(self.rfile.read(length) or b"{}")
        except (ValueError, RecursionError):
            self._error(400, "the request is not JSON")
            return None
        if not isinstance(payload, dict):
            self._error(400, "the request must be a JSON object")
            return None
        return payload

    def _refuse_origin(self) -> None:
        origin = (self.headers.get("Origin") or self.headers.get("Host") or "?")[:200]
        self.study.report(f"refused a request from {origin!r}: only this server's own page may use the study "
                          "(allow another with --allow-origin ORIGIN)")
        self._error(403, "forbidden: this study is only for the page served here")

    # routes ----------------------------------------------------------------------------------------------------
    def do_HEAD(self) -> None:  # noqa: N802 - http.server's name
        self.do_GET()

    def do_GET(self) -> None:  # noqa: N802
        if not self._allowed_origin():
            self._refuse_origin()
            return
        path = urllib.parse.urlsplit(self.path).path
        study = self.study
        try:
            if path in ("/", "/index.html"):
                self._send(200, study._page, "text/html; charset=utf-8", {
                    "Content-Security-Policy": "default-src 'self'; script-src 'self' 'unsafe-inline'; "
                                               "style-src 'self' 'unsafe-inline'; media-src 'self'; "
                                               "connect-src 'self'; frame-ancestors 'none'"})
            elif path in study.head_files:
                self._send(200, *study.head_files[path]())
            elif path == "/api/study":
                self._json(200, study.study_info())
            elif path == "/api/state":
                self._json(200, study.with_videos(study.store.state(self._query().get("participant", ""))))
            elif path.startswith("/stimuli/"):
                self._video(urllib.parse.unquote(path[len("/stimuli/"):]))
            elif path in ("/admin/export.csv", "/admin/progress"):
                if not self._token_ok():
                    study.report("refused an organiser's request without the right token")
                    self._error(401, "the organiser's token is needed (printed when the server started)")
                elif path == "/admin/progress":
                    self._json(200, study.store.progress())
                else:
                    self._send(200, study.store.export_csv().encode(), "text/csv; charset=utf-8",
                               {"Content-Disposition": 'attachment; filename="ballots.csv"'})
            else:
                self._error(404, "not found: the study is at /")
        except StudyStoreError as error:
            self._error(error.status, str(error))
        except sqlite3.Error as error:
            study.report(f"the database cannot be read: {error}")
            self._error(503, f"the study's database cannot be read ({error}); try again")

    def do_POST(self) -> None:  # noqa: N802
        if not self._allowed_origin():
            self._refuse_origin()
            return
        path = urllib.parse.urlsplit(self.path).path
        study = self.study
        payload = self._body()
        if payload is None:
            return
        try:
            if path == "/api/participants":
                refused = study.arrivals.admit(self.client_address[0])
                if refused is not None:
                    study._quiet(f"refused a new participant from {self.client_address[0]}: {refused}")
                    self._send(429, json.dumps({"error": f"too many new participants: {refused}; try again in a "
                                                         "minute"}).encode(), "application/json",
                               {"Retry-After": "60"})
                    return
                participant = study.store.new_participant()
                progress = study.store.progress()
                study.report(f"participant {progress['participants']} arrived ({participant})")
                self._json(201, study.with_videos(study.store.state(participant)))
            elif path == "/api/answer":
                state = study.store.answer(payload.get("participant"), payload.get("position"),
                                           payload.get("answer"), payload.get("seconds"))
                if state["finished"] and state["answered"] == payload.get("position"):
                    study.report(f"participant {state['participant']} finished")
                self._json(200, study.with_videos(state))
            else:
                self._error(404, "not found")
        except StudyStoreError as error:
            self._error(error.status, str(error))
        except sqlite3.Error as error:
            study.report(f"an answer could not be saved: {error}")
            self._error(503, f"the answer could not be saved ({error}); it will be sent again")

    def _video(self, name: str) -> None:
        """A video of the manifest, whole or the byte range asked for, read by seeking and sent in blocks; a
        video's head frames as they were checked at the start."""
        if name in self.study.motion_bodies:
            self._send(200, self.study.motion_bodies[name], "application/json")
            return
        path = self.study.files.get(name)
        if path is None:
            self._error(404, "no such video")
            return
        try:
            real = path.resolve(strict=True)
            if not real.is_relative_to(self.study.folder):  # a link swapped in after the start
                self._error(404, "no such video")
                return
            handle = open(real, "rb")  # noqa: SIM115 - closed below, after the sending
        except OSError as error:
            self._error(404, f"the video cannot be read ({error.strerror or error})")
            return
        with handle:
            size = os.fstat(handle.fileno()).st_size
            headers = {"Accept-Ranges": "bytes"}
            status, start, end = 200, 0, size - 1
            match = _RANGE.match(self.headers.get("Range", "").strip())
            if match and (match[1] or match[2]):
                if match[1]:
                    start, end = int(match[1]), min(int(match[2]) if match[2] else size - 1, size - 1)
                else:
                    start, end = max(0, size - int(match[2])), size - 1
                if start > end or start >= size:
                    self._send(416, b"", "video/mp4", {"Content-Range": f"bytes */{size}"})
                    return
                status = 206
                headers["Content-Range"] = f"bytes {start}-{end}/{size}"
            self.send_response(status)
            kind = "application/json" if name.endswith(".json") else "video/mp4"
            for key, value in {"Content-Type": kind, "Content-Length": str(end - start + 1), **SAFE_HEADERS,
                               **headers}.items():
                self.send_header(key, value)
            self.end_headers()
            if self.command == "HEAD":
                return
            handle.seek(start)
            left = end - start + 1
            while left > 0:
                block = handle.read(min(VIDEO_BLOCK_BYTES, left))
                if not block:
                    break
                self.wfile.write(block)
                left -= len(block)
