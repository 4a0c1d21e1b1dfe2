"""`prosody stream` as it is used: driven through a pipe at real-time pace, stopped with Ctrl-C, serving
frames and the page over a WebSocket to several clients, some of them misbehaving."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import threading
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest
import soundfile
from conftest import REPO, segments

from prosody.cli import main
from prosody.fap.fapfile import read_fap
from prosody.live.converter import LiveFrame
from prosody.motion.face.lips import LIP_FAPS

PROSODY = [sys.executable, "-m", "prosody"]
SAMPLE = REPO / "samples" / "arctic_a0009.wav"
ENV = {**os.environ, "PYTHONUNBUFFERED": "1"}


class _Reader(threading.Thread):
    """Reads a process's standard output line by line, noting when each line arrived."""

    def __init__(self, stream) -> None:
        super().__init__(daemon=True)
        self.stream = stream
        self.lines: list[tuple[float, str]] = []

    def run(self) -> None:
        for line in iter(self.stream.readline, b""):
            self.lines.append((time.monotonic(), line.decode()))


def _started(process: subprocess.Popen, timeout_s: float = 120.0) -> _Reader:
    """Waits for the command's readiness line on its standard error (it is reading its input), not on the
    clock: a busy machine can take seconds to start Python. Returns the reader of the rest of standard error."""
    errors = _Reader(process.stderr)
    errors.start()
    deadline = time.monotonic() + timeout_s
    while not any("prosody stream: reading" in line for _, line in errors.lines):
        assert process.poll() is None, "".join(line for _, line in errors.lines)
        assert time.monotonic() < deadline, "no readiness line"
        time.sleep(0.02)
    return errors


def _unread_bytes(pipe) -> int:
    """Bytes written into a pipe that its reader has not taken yet (Linux's FIONREAD works on either end)."""
    import fcntl
    import struct
    import termios

    return struct.unpack("i", fcntl.ioctl(pipe.fileno(), termios.FIONREAD, b"\0" * 4))[0]


def _waits_on_its_pipe(process: subprocess.Popen) -> bool:
    """The process's main thread is blocked reading a pipe (its standard input), by the kernel's account;
    where the kernel hides that, that it sleeps."""
    proc = Path("/proc") / str(process.pid)
    try:
        channel = (proc / "wchan").read_text()
        if channel not in ("", "0"):
            return "pipe_read" in channel
        return (proc / "stat").read_text().rsplit(")", 1)[1].split()[0] == "S"
    except OSError:
        return False


def _pcm16(samples: np.ndarray) -> bytes:
    return (np.clip(samples, -1, 1) * 32767).astype("<i2").tobytes()


@pytest.mark.slow
def test_pipe_at_real_time_pace_gives_every_frame_in_time_and_in_order():
    samples, rate = soundfile.read(SAMPLE)
    with subprocess.Popen([*PROSODY, "stream", "-", "--raw-rate", str(rate), "-o", "-"], stdin=subprocess.PIPE,
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=ENV) as process:
        reader = _Reader(process.stdout)
        reader.start()
        errors = _started(process)
        chunk = rate // 50  # 20 ms
        written = []  # (time, samples written so far)
        start = time.monotonic()
        for offset in range(0, samples.size, chunk):
            delay = start + offset / rate - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            process.stdin.write(_pcm16(samples[offset:offset + chunk]))
            process.stdin.flush()
            written.append((time.monotonic(), min(samples.size, offset + chunk)))
        input_closed = time.monotonic()
        process.stdin.close()
        assert process.wait(timeout=120) == 0, "".join(line for _, line in errors.lines)
        reader.join(timeout=10)
    frames = [json.loads(line) for _, line in reader.lines]
    expected = int(np.ceil(samples.size / rate * 30 - 1e-9))
    assert [frame["frame"] for frame in frames] == list(range(expected))
    assert all(frame["time_s"] == pytest.approx(frame["frame"] / 30, abs=1e-6) for frame in frames)
    expected = {str(fap) for fap in (*LIP_FAPS, 31, 32, 33, 34, 48, 49, 50)}
    assert all(set(frame["faps"]) == expected for frame in frames)
    assert min(frame["faps"]["31"] for frame in frames) >= 0
    assert np.std([frame["faps"]["49"] for frame in frames]) > 10  # the head moves
    # no frame comes out before the audio up to its look-ahead (100 ms) had been written
    times = np.array([t for t, _ in written])
    counts = np.array([n for _, n in written])
    for (arrived, _), frame in zip(reader.lines, frames, strict=True):
        needed = (frame["frame"] / 30 + 0.1) * rate
        first_written = times[np.searchsorted(counts, min(needed, samples.size))]
        assert arrived >= first_written
    # and they come out while the audio is still arriving, not at its end
    before_end = sum(arrived < input_closed for arrived, _ in reader.lines)
    assert before_end > 0.8 * len(frames)


def test_wav_stream_on_stdin_and_a_fap_written_at_the_end(tmp_path):
    out = tmp_path / "live.fap"
    with open(SAMPLE, "rb") as audio:
        result = subprocess.run([*PROSODY, "stream", "-", "-o", str(out)], stdin=audio, capture_output=True,
                                env=ENV, timeout=60)
    assert result.returncode == 0, result.stderr.decode()
    stream = read_fap(out).stream
    converted = subprocess.run([*PROSODY, "convert", str(SAMPLE), "-o", str(tmp_path / "offline.fap")],
                               capture_output=True, env=ENV, timeout=60)
    assert converted.returncode == 0
    assert abs(stream.n_frames - read_fap(tmp_path / "offline.fap").stream.n_frames) <= 1
    assert list(stream.active_faps) == sorted([*LIP_FAPS, 31, 32, 33, 34, 48, 49, 50])
    assert b"end of input" in result.stderr


@pytest.mark.parametrize("stop", [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_flushes_the_last_frames_and_writes_the_file_whole(tmp_path, stop):
    out = tmp_path / "stopped.fap"
    with subprocess.Popen([*PROSODY, "stream", "-", "--raw-rate", "16000", "-o", str(out)],
                          stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=ENV) as process:
        errors = _started(process)
        process.stdin.write(_pcm16(segments(16000, (0.6, 150, 0.5), (0.4, 220, 0.5))))
        process.stdin.flush()
        deadline = time.monotonic() + 120
        settled = 0  # the command has taken it all and waits for more, seen on consecutive looks
        while settled < 5 and time.monotonic() < deadline:
            settled = settled + 1 if not _unread_bytes(process.stdin) and _waits_on_its_pipe(process) else 0
            time.sleep(0.02)
        # stdin stays open, as a microphone's would: the signal stops the wait for more
        process.send_signal(stop)
        process.wait(timeout=120)
        errors.join(timeout=10)
    err = "".join(line for _, line in errors.lines)
    assert process.returncode == 0, err
    assert "the last frames flushed" in err
    stream = read_fap(out).stream
    assert stream.n_frames == 30  # the whole second given, its last frames flushed at the stop
    assert not list(tmp_path.glob(".*.part*"))


@pytest.mark.parametrize("argv, message", [
    (["stream", "x.wav"], "give -o OUT"),
    (["stream", "-o", "-"], "give an input"),
    (["stream", "x.wav", "--mic", "-o", "-"], "not both"),
    (["stream", "-", "-o", "-", "--realtime"], "--realtime paces a file"),
    (["stream", "x.wav", "-o", "-", "--raw-rate", "16000"], "describe standard input"),
    (["stream", "x.wav", "-o", "-", "--condition", "truth"], "invalid choice"),
    (["stream", "x.wav", "-o", "-", "--model", "arx"], "not offered live"),
    (["stream", "x.wav", "-o", "-", "--model", "pad"], "--model pad: Jia et al.'s gestures take a whole prosodic word"),
    (["stream", "x.wav", "-o", "-", "--model", "pad-random"], "--model pad-random: Jia et al.'s random baseline"),
    (["stream", "x.wav", "-o", "-", "--format", "fap"], "--format names"),
    (["stream", "x.wav", "-o", "-", "--lookahead-ms", "-3"], "milliseconds"),
    (["stream", "x.wav", "-o", "-", "--listen", "here:port"], "HOST:PORT"),
    (["stream", "x.wav", "-o", "x.fap", "--loop"], "never be written"),
    (["stream", "-", "-o", "-", "--loop"], "--loop plays a file"),
    (["stream", "-", "-o", "-", "--raw-rate", "4000"], "8000 to 768000"),
    (["stream", "-", "-o", "-", "--raw-rate", "16000", "--raw-channels", "0"], "1 to 64"),
    (["train", "--data", ".", "-o", "m.json", "--lookahead-ms", "100"], "add --kind live"),
    # the output's format is known before the session (it ran the whole --realtime session first)
    (["stream", "x.wav", "--realtime", "-o", "nowhere.txt"], "give --format NAME"),
    (["stream", "x.wav", "-o", "x.glb"], "a live stream writes motion"),
    (["stream", "x.wav", "-o", "x.rhubarb.tsv"], "not rhubarb-tsv"),
    (["stream", "x.wav", "--face", "me.png", "-o", "-"], "give --listen too"),
])
def test_usage_errors_exit_2_with_one_line(argv, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    soundfile.write(tmp_path / "x.wav", segments(16000, (0.5, 150, 0.5)), 16000)
    try:
        code = main(argv)
    except SystemExit as stop:  # argparse's own checks
        code = stop.code
    assert code == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_malformed_input_mid_stream_is_one_line_and_exit_1(tmp_path):
    good = (segments(16000, (0.5, 150, 0.5)).astype("<f4")).tobytes()
    bad = np.array([np.nan], dtype="<f4").tobytes()
    result = subprocess.run([*PROSODY, "stream", "-", "--raw-rate", "16000", "--raw-format", "f32le", "-o", "-"],
                            input=good + bad + good, capture_output=True, env=ENV, timeout=60)
    assert result.returncode == 1
    said = [line for line in result.stderr.decode().splitlines() if not line.startswith("prosody stream: reading")]
    assert said == ["prosody stream: error: sample value nan is not finite; audio must have no NaN or infinity"]
    assert len(result.stdout.decode().splitlines()) >= 5  # the frames before the fault were given out


# the server -------------------------------------------------------------------------------------------------
def _frames(k0: int, n: int) -> list[LiveFrame]:
    return [LiveFrame(k, k / 30, {31: 0.0, 48: float(k)}) for k in range(k0, k0 + n)]


def _receive_all(connection, timeout_s: float = 1.0, *, controls: bool = False) -> list[dict]:
    """Every message until none comes for ``timeout_s``; the expressivity messages only if ``controls``."""
    from websockets.exceptions import ConnectionClosed

    messages = []
    try:
        while True:
            message = json.loads(connection.recv(timeout=timeout_s))
            if controls or message["type"] != "expressivity":
                messages.append(message)
    except (TimeoutError, ConnectionClosed):
        return messages


def test_page_is_served_and_unknown_paths_are_404(frame_server):
    with urllib.request.urlopen(frame_server.url, timeout=5) as response:
        page = response.read().decode()
        assert response.headers["Content-Type"].startswith("text/html")
    assert "<canvas" in page and "WebSocket" in page
    with pytest.raises(urllib.error.HTTPError) as error:
        urllib.request.urlopen(frame_server.url + "nothing", timeout=5)
    error.value.close()
    assert error.value.code == 404


@pytest.mark.slow
def test_every_client_gets_the_input_frames_and_a_second_can_join(frame_server):
    from websockets.sync.client import connect

    url = f"ws://127.0.0.1:{frame_server.port}/stream"
    with connect(url) as first:
        time.sleep(0.2)
        frame_server.publish(_frames(0, 10))
        with connect(url) as second:
            time.sleep(0.2)
            frame_server.publish(_frames(10, 10))
            got_second = _receive_all(second)
        got_first = _receive_all(first)
    assert [m["frame"] for m in got_first] == list(range(20))
    assert [m["frame"] for m in got_second] == list(range(10, 20))
    assert all(m["source"] == "input" for m in got_first)
    assert sum("connected" in line and "disconnected" not in line for line in frame_server.lines) == 2


@pytest.mark.slow
def test_a_stalled_reader_and_a_vanished_client_do_not_stop_the_others(frame_server):
    import socket

    from websockets.sync.client import connect

    url = f"ws://127.0.0.1:{frame_server.port}/stream"
    quiet = socket.create_connection(("127.0.0.1", frame_server.port))
    quiet.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # a reader that takes almost nothing
    with connect(url) as good, connect(url, sock=quiet) as stalled, connect(url) as vanished:
        time.sleep(0.2)
        vanished.socket.shutdown(socket.SHUT_RDWR)  # gone without a closing handshake
        received: list[dict] = []
        reader = threading.Thread(target=lambda: received.extend(_receive_all(good, 2.0)))
        reader.start()
        for batch in range(40):  # 4000 frames: more than a stalled client's queue and buffers hold
            frame_server.publish(_frames(batch * 100, 100))
            time.sleep(0.02)
        reader.join()
        assert stalled.protocol.state.name == "OPEN"
    assert [m["frame"] for m in received] == list(range(4000))
    stalls = [line for line in frame_server.lines if "not reading" in line]
    assert len(stalls) == 1
    assert sum("disconnected" in line for line in frame_server.lines) >= 1


@pytest.mark.slow
def test_client_audio_gives_frames_to_that_client_and_bad_messages_are_told_once(frame_server):
    from websockets.sync.client import connect

    samples = segments(16000, (0.6, 150, 0.5), (0.4, 230, 0.5))
    url = f"ws://127.0.0.1:{frame_server.port}/stream"
    with connect(url) as talker, connect(url) as watcher:
        talker.send("not json")
        talker.send(b"\x00\x01")  # audio before start
        talker.send(b"\x00\x01")
        talker.send(json.dumps({"type": "start", "sample_rate": 16000, "encoding": "f32le"}))
        for start in range(0, samples.size, 1600):
            talker.send(samples[start:start + 1600].astype("<f4").tobytes())
        talker.send(json.dumps({"type": "stop"}))
        got = _receive_all(talker, 3.0)
        watched = _receive_all(watcher, 0.3)
    frames = [m for m in got if m["type"] == "frame"]
    errors = [m for m in got if m["type"] == "error"]
    assert [m["frame"] for m in frames] == list(range(30))
    assert all(m["source"] == "client" for m in frames)
    assert len(errors) == 3  # each bad message is answered ...
    assert sum("before a start" in line for line in frame_server.lines) == 1  # ... and reported once
    assert watched == []  # a client's own audio drives its own face only
    assert frame_server.audio_messages == 10


def test_client_audio_that_is_not_finite_stops_that_client_only(frame_server):
    from websockets.sync.client import connect

    url = f"ws://127.0.0.1:{frame_server.port}/stream"
    with connect(url) as broken, connect(url) as fine:
        broken.send(json.dumps({"type": "start", "sample_rate": 16000, "encoding": "f32le"}))
        broken.send(np.array([np.nan] * 100, dtype="<f4").tobytes())
        time.sleep(0.3)
        frame_server.publish(_frames(0, 5))
        assert [m["frame"] for m in _receive_all(fine, 0.5)] == list(range(5))
        errors = [m for m in _receive_all(broken, 0.5) if m["type"] == "error"]
    assert "not finite" in errors[0]["message"]


@pytest.mark.slow
def test_stream_command_serves_a_file_to_a_client(tmp_path):
    from websockets.sync.client import connect

    with subprocess.Popen([*PROSODY, "stream", str(SAMPLE), "--realtime", "--listen", "127.0.0.1:0", "-o",
                           str(tmp_path / "out.jsonl")], stderr=subprocess.PIPE, env=ENV) as process:
        line = process.stderr.readline().decode()
        assert "serving the face at http://127.0.0.1:" in line, line
        port = int(line.split("http://127.0.0.1:")[1].split("/")[0])
        with connect(f"ws://127.0.0.1:{port}/stream") as client:
            messages = _receive_all(client, 5.0)
        process.communicate(timeout=30)
    assert process.returncode == 0
    frames = [m["frame"] for m in messages if m["type"] == "frame"]
    assert frames == list(range(frames[0], frames[0] + len(frames))) and len(frames) > 60
    assert messages[-1] == {"type": "end"}  # the page is told the stream ended
    written = [json.loads(x) for x in Path(tmp_path / "out.jsonl").read_text().splitlines()]
    assert len(written) == 93


def test_mic_without_sounddevice_says_what_to_install(capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "sounddevice", None)  # as on a machine without the mic extra
    assert main(["stream", "--mic", "-o", "-"]) == 2
    err = capsys.readouterr().err
    assert "visual-prosody[mic]" in err and err.count("\n") == 1


def test_mic_without_portaudio_or_a_device_says_what_to_do(capsys, monkeypatch):
    import types

    class Missing:  # the package imports, its PortAudio library does not load
        def find_spec(self, name, path=None, target=None):
            if name == "sounddevice":
                raise OSError("PortAudio library not found")

    monkeypatch.delitem(sys.modules, "sounddevice", raising=False)
    monkeypatch.setattr(sys, "meta_path", [Missing(), *sys.meta_path])
    assert main(["stream", "--mic", "-o", "-"]) == 2
    err = capsys.readouterr().err
    assert "apt install libportaudio2" in err and err.count("\n") == 1

    class PortAudioError(Exception):
        pass

    def no_device(**options):
        raise PortAudioError("Error querying device -1")

    fake = types.SimpleNamespace(PortAudioError=PortAudioError, InputStream=no_device)
    monkeypatch.setattr(sys, "meta_path", [m for m in sys.meta_path if not isinstance(m, Missing)])
    monkeypatch.setitem(sys.modules, "sounddevice", fake)
    assert main(["stream", "--mic", "-o", "-"]) == 2
    err = capsys.readouterr().err
    assert "no microphone to read at 16000 Hz (Error querying device -1)" in err and err.count("\n") == 1


def test_only_the_servers_own_page_may_open_the_stream():
    # a page on another site (or one whose DNS name was pointed at this machine) must not watch the stream
    # or send audio; clients that are not browsers send no Origin and are served
    import socket

    from websockets.exceptions import InvalidStatus
    from websockets.sync.client import connect

    from prosody.live.converter import LiveConverter
    from prosody.live.server import FrameServer

    lines: list[str] = []
    server = FrameServer("127.0.0.1", 0, make_converter=lambda rate: LiveConverter(rate), report=lines.append,
                         allow_origins=["https://studio.example:8443/"]).start()
    try:
        def opened(host: str, origin: str | None):
            # the request names ``host`` (its Host header) whatever address it is sent to
            sock = socket.create_connection(("127.0.0.1", server.port))
            return connect(f"ws://{host}:{server.port}/stream", sock=sock, origin=origin, open_timeout=5)

        own = [("127.0.0.1", f"http://127.0.0.1:{server.port}"), ("localhost", f"http://localhost:{server.port}"),
               ("127.0.0.1", None), ("127.0.0.1", "https://studio.example:8443")]
        for host, origin in own:
            with opened(host, origin) as client:
                assert client.protocol.state.name == "OPEN"
        foreign = [("127.0.0.1", "https://evil.example"), ("127.0.0.1", f"http://127.0.0.1:{server.port + 1}"),
                   ("rebound.example", f"http://rebound.example:{server.port}"), ("127.0.0.1", "null")]
        for host, origin in foreign:
            with pytest.raises(InvalidStatus) as refused:
                opened(host, origin)
            assert refused.value.response.status_code == 403
        assert sum("refused a WebSocket" in line for line in lines) == len(foreign)
        assert any("'https://evil.example'" in line and "--allow-origin" in line for line in lines)
    finally:
        server.close(drain_s=0.2)


def test_close_is_bounded_with_a_stalled_client_and_publish_after_close_is_refused():
    import socket

    from websockets.sync.client import connect

    from prosody.live.converter import LiveConverter
    from prosody.live.server import FrameServer, ServerClosedError

    server = FrameServer("127.0.0.1", 0, make_converter=lambda rate: LiveConverter(rate),
                         report=lambda line: None).start()
    quiet = socket.create_connection(("127.0.0.1", server.port))
    quiet.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    with connect(f"ws://127.0.0.1:{server.port}/", sock=quiet, close_timeout=0.2):
        for batch in range(20):  # more than its buffers hold: it never reads, nor answers the close
            server.publish(_frames(batch * 100, 100))
        time.sleep(0.3)
        started = time.monotonic()
        server.close(drain_s=0.5)
        assert time.monotonic() - started < 0.5 + 6.5  # about 1 s; it used to return with the thread alive
        assert server._thread is not None and not server._thread.is_alive()
    with pytest.raises(ServerClosedError):
        server.publish(_frames(0, 1))


def test_hostile_control_messages_are_refused_and_the_server_goes_on(frame_server):
    from websockets.sync.client import connect

    url = f"ws://127.0.0.1:{frame_server.port}/stream"
    with connect(url) as client:
        client.send('{"type": "start", "sample_rate": 1e400}')  # JSON's way to say infinity
        client.send("[" * 100000 + "]" * 100000)  # deeper than any parser's recursion
        client.send('{"type": "stop"}')  # nothing was started: said so, not called an unknown type
        errors = [m for m in _receive_all(client, 1.0) if m["type"] == "error"]
        assert len(errors) == 3 and "cannot start" in errors[0]["message"]
        assert errors[2]["message"] == "stop: no audio was started (send start first)"
        frame_server.publish(_frames(0, 3))
        assert [m["frame"] for m in _receive_all(client, 0.5)] == [0, 1, 2]


@pytest.mark.slow
def test_a_client_changes_the_expressivity_of_its_own_audio_and_bad_controls_are_refused(frame_server):
    from websockets.sync.client import connect

    from prosody.live.converter import LiveConverter
    from prosody.motion.expressivity import Expressivity

    samples = segments(16000, (0.6, 150, 0.5), (0.4, 230, 0.5), (0.6, 140, 0.5))
    url = f"ws://127.0.0.1:{frame_server.port}/stream"
    with connect(url) as talker:
        greeting = json.loads(talker.recv(timeout=2))
        talker.send(json.dumps({"type": "expressivity", "spatial": 5}))
        talker.send(json.dumps({"type": "expressivity", "loudness": 1}))
        talker.send(json.dumps({"type": "expressivity", "spatial": -1, "power": 0.5}))
        talker.send(json.dumps({"type": "start", "sample_rate": 16000, "encoding": "f32le"}))
        talker.send(samples.astype("<f4").tobytes())
        talker.send(json.dumps({"type": "stop"}))
        got = _receive_all(talker, 3.0, controls=True)
    # a server without an input of its own: the controls are the client's, neutral to begin with
    assert greeting["type"] == "expressivity" and greeting["source"] == "client"
    assert greeting["controls"] == Expressivity().as_dict() and greeting["ranges"]["spatial"] == [-1, 1]
    errors = [m["message"] for m in got if m["type"] == "error"]
    assert "spatial must be a number in [-1, 1], got 5" in errors[0] and "unknown expressivity control" in errors[1]
    answers = [m for m in got if m["type"] == "expressivity"]
    assert answers == [{**greeting, "controls": {**greeting["controls"], "spatial": -1.0, "power": 0.5}}]
    # the client's frames are those of a converter made with these controls
    expected = LiveConverter(16000, expressivity=Expressivity(spatial=-1, power=0.5))
    reference = expected.push(samples.astype("<f4").astype(float)) + expected.finish()  # as sent: float32
    frames = [m for m in got if m["type"] == "frame"]
    assert len(frames) == len(reference) == 48
    for message, frame in zip(frames, reference, strict=True):
        assert message["faps"] == {str(fap): round(value, 3) for fap, value in frame.faps.items()}


def test_a_page_changes_the_expressivity_of_the_commands_input_for_every_client():
    from websockets.sync.client import connect

    from prosody.live.converter import LiveConverter
    from prosody.live.server import FrameServer
    from prosody.motion.expressivity import Expressivity

    applied: list[Expressivity] = []
    lines: list[str] = []
    server = FrameServer("127.0.0.1", 0, make_converter=lambda rate: LiveConverter(rate), report=lines.append,
                         expressivity=Expressivity(fluidity=0.5), on_expressivity=applied.append).start()
    try:
        url = f"ws://127.0.0.1:{server.port}/stream"
        with connect(url) as setter, connect(url) as watcher:
            greetings = [json.loads(setter.recv(timeout=2)), json.loads(watcher.recv(timeout=2))]
            setter.send(json.dumps({"type": "expressivity", "activation": 0}))
            told = [_receive_all(client, 0.5, controls=True) for client in (setter, watcher)]
    finally:
        server.close(drain_s=0.2)
    assert all(g["source"] == "input" and g["controls"]["fluidity"] == 0.5 for g in greetings)
    assert applied == [Expressivity(activation=0, fluidity=0.5)]
    for messages in told:  # both pages are shown the new controls of the input
        assert [m["controls"]["activation"] for m in messages if m["type"] == "expressivity"] == [0.0]
    assert any("set the input's expressivity: activation 0" in line for line in lines)


@pytest.mark.slow
def test_stream_command_applies_a_pages_expressivity_from_the_next_chunk(tmp_path):
    # spatial -1 halves the head about rest: the frames after the change are half those of a neutral run
    from websockets.sync.client import connect

    neutral, changed = tmp_path / "neutral.jsonl", tmp_path / "changed.jsonl"
    assert main(["stream", str(SAMPLE), "-o", str(neutral)]) == 0
    with subprocess.Popen([*PROSODY, "stream", str(SAMPLE), "--realtime", "--listen", "127.0.0.1:0", "-o",
                           str(changed)], stderr=subprocess.PIPE, env=ENV) as process:
        line = process.stderr.readline().decode()
        port = int(line.split("http://127.0.0.1:")[1].split("/")[0])
        with connect(f"ws://127.0.0.1:{port}/stream") as client:
            client.send(json.dumps({"type": "expressivity", "spatial": -1}))
            _receive_all(client, 5.0)
        _, err = process.communicate(timeout=30)
    assert process.returncode == 0 and b"set the input's expressivity: spatial -1" in err
    before = [json.loads(x)["faps"] for x in neutral.read_text().splitlines()]
    after = [json.loads(x)["faps"] for x in changed.read_text().splitlines()]
    assert len(before) == len(after) == 93
    late = [(b[str(fap)], a[str(fap)]) for b, a in zip(before[-30:], after[-30:], strict=True) for fap in (48, 49, 50)
            if abs(b[str(fap)]) > 100]
    assert len(late) > 30
    np.testing.assert_allclose([a for _, a in late], [b / 2 for b, _ in late], rtol=0.02, atol=2)


def test_the_input_sound_goes_to_the_clients_that_ask_for_it():
    from websockets.exceptions import ConnectionClosed
    from websockets.sync.client import connect

    from prosody.live.converter import LiveConverter
    from prosody.live.server import AUDIO_HEADER, FrameServer

    server = FrameServer("127.0.0.1", 0, make_converter=lambda rate: LiveConverter(rate), report=lambda _: None)
    server.start()
    rate = 16000
    sound = np.random.default_rng(0).uniform(-1.2, 1.2, int(1.05 * rate))  # beyond full scale: clipped
    url = f"ws://127.0.0.1:{server.port}/stream"
    with connect(url) as listener, connect(url) as watcher:
        listener.send(json.dumps({"type": "audio", "on": True}))
        time.sleep(0.2)
        for start in range(0, sound.size, 160):  # 10 ms at a time, as a file is read
            server.publish_audio(sound[start:start + 160], rate)
        server.publish(_frames(0, 3))
        server.close(drain_s=0.5)  # sends the last 0.05 s too
        received: dict[str, list] = {"listener": [], "watcher": []}
        for name, connection in (("listener", listener), ("watcher", watcher)):
            with contextlib.suppress(TimeoutError, ConnectionClosed):
                while True:
                    received[name].append(connection.recv(timeout=1.0))
    binary = [m for m in received["listener"] if isinstance(m, bytes)]
    assert len(binary) == 11  # ten of 0.1 s and the rest, flushed at the end
    assert not any(isinstance(m, bytes) for m in received["watcher"])  # none to the one that did not ask
    assert sum('"frame"' in m for m in received["watcher"]) == 3  # who still gets the frames
    starts, got = [], []
    for piece in binary:
        start, piece_rate = AUDIO_HEADER.unpack_from(piece)
        assert piece_rate == rate
        starts.append(start)
        got.append(np.frombuffer(piece[AUDIO_HEADER.size:], dtype="<i2"))
    assert starts == pytest.approx(np.cumsum([0] + [len(g) for g in got[:-1]]) / rate)
    expected = (np.clip(sound, -1, 1) * 32767).round()
    assert np.array_equal(np.concatenate(got), expected)


@pytest.mark.slow
def test_loop_starts_with_the_first_page_and_plays_the_file_again(tmp_path):
    from websockets.sync.client import connect

    with subprocess.Popen([*PROSODY, "stream", str(SAMPLE), "--loop", "--listen", "127.0.0.1:0"],
                          stderr=subprocess.PIPE, env=ENV) as process:
        line = process.stderr.readline().decode()
        port = int(line.split("http://127.0.0.1:")[1].split("/")[0])
        assert "starts when the first page connects" in process.stderr.readline().decode()
        time.sleep(1.0)  # nothing is played to no one
        with connect(f"ws://127.0.0.1:{port}/stream") as client:
            messages: list[int] = []
            deadline = time.monotonic() + 4.5
            while time.monotonic() < deadline:
                message = json.loads(client.recv(timeout=5))
                if message["type"] == "frame":
                    messages.append(message["frame"])
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=30)
    assert process.returncode == 0
    assert messages[0] == 0  # the file waited for the page
    restart = messages.index(0, 1)
    assert messages[:restart] == list(range(93)) and messages[restart:] == list(range(len(messages) - restart))
    assert "pass(es) of the file" in err.decode()


def test_the_live_page_answers_its_own_host_only_with_safe_headers():
    """The page and its files are served to requests naming this server (an address, localhost, or the host
    of an --allow-origin), with a CSP that forbids framing, nosniff and no referrer; another name pointed at
    this machine (DNS rebinding) gets 421, a request with two Upgrade or two Host headers 400, not a
    traceback."""
    import socket

    from prosody.live.converter import LiveConverter
    from prosody.live.server import FrameServer

    lines: list[str] = []
    server = FrameServer("127.0.0.1", 0, make_converter=lambda rate: LiveConverter(rate), report=lines.append,
                         allow_origins=["https://studio.example:8443/"]).start()

    def ask(*headers: str, path: str = "/") -> tuple[int, str]:
        with socket.create_connection(("127.0.0.1", server.port), timeout=5) as sock:
            request = f"GET {path} HTTP/1.1\r\n" + "".join(f"{h}\r\n" for h in headers) + "Connection: close\r\n\r\n"
            sock.sendall(request.encode())
            answer = b""
            while chunk := sock.recv(65536):
                answer += chunk
        head = answer.split(b"\r\n\r\n", 1)[0].decode("latin-1")
        return int(head.split()[1]), head.lower()

    try:
        for host in (f"127.0.0.1:{server.port}", f"localhost:{server.port}", "studio.example:8443"):
            status, head = ask(f"Host: {host}")
            assert status == 200
            assert "frame-ancestors 'none'" in head and "x-content-type-options: nosniff" in head
            assert "referrer-policy: no-referrer" in head
        status, head = ask(f"Host: 127.0.0.1:{server.port}", path="/head.js")
        assert status == 200 and "nosniff" in head
        assert ask(f"Host: rebound.example:{server.port}")[0] == 421
        assert ask(f"Host: rebound.example:{server.port}", path="/head.json")[0] == 421
        assert ask(f"Host: 127.0.0.1:{server.port}", "Upgrade: websocket", "Upgrade: websocket")[0] == 400
        assert ask(f"Host: 127.0.0.1:{server.port}", f"Host: 127.0.0.1:{server.port}")[0] == 400
        assert not any("Traceback" in line for line in lines)
    finally:
        server.close(drain_s=0.2)
