"""A live session: one audio source through a :class:`~prosody.live.converter.LiveConverter` to every sink.

``prosody stream`` is a shell over this module. From Python::

    from prosody.live.session import AudioSource, StreamOptions, StreamSession

    options = StreamOptions(output="talk.fap", livelink=("127.0.0.1",), converter={"seed": 3})
    result = StreamSession(options).run(AudioSource("talk.wav"))

Sinks are the page server (``listen``), the Live Link and VMC senders, the output (a file written when the
stream ends, JSON lines as they come, or standard output) and any callables given to :meth:`StreamSession.run`,
each called with the frames that became final. A session's options are checked once, before anything listens
or reads: :func:`check_session` says what is wrong in the words of the caller (Python's keyword names by
default; the command's flags when the command calls it).
"""

from __future__ import annotations

import contextlib
import queue
import signal
import sys
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from audio_features.atomic import atomic_write
from audio_features.pcm import PcmFormat

from ..errors import ConfigError
from ..motion.expressivity import Expressivity
from .converter import (
    DEFAULT_LOOKAHEAD_MS,
    FrameRecorder,
    LiveConverter,
    LiveFrame,
    byte_chunks,
    file_chunks,
    microphone_chunks,
)

#: Sample rate a session's converter is tried at when no input is read (a page brings its own rate).
PROBE_RATE_HZ = 16000

Sink = Callable[[list[LiveFrame]], object]


def python_name(name: str) -> str:
    """How :func:`check_session` names an option by default: its keyword (``loop=``)."""
    return f"{name}="


@dataclass(frozen=True)
class AudioSource:
    """Where a session's audio comes from: a file, standard input (``"-"``) or the microphone.

    Parameters
    ----------
    input : str or None
        A file, or ``"-"`` for standard input (a WAV stream, or raw samples described by ``raw``).
    mic : bool
        Read the default microphone instead (needs the ``sounddevice`` package).
    mic_rate : int
        Sample rate asked of the microphone, in Hz.
    raw : PcmFormat or None
        Raw samples on standard input (None: a WAV stream).
    realtime : bool
        Read a file no faster than it plays.
    """

    input: str | None = None
    mic: bool = False
    mic_rate: int = 16000
    raw: PcmFormat | None = None
    realtime: bool = False

    @property
    def arrives_live(self) -> bool:
        """True for standard input and microphones, which come at their own pace."""
        return self.mic or self.input == "-"

    @property
    def name(self) -> str:
        """The stream's name: the file's stem, or ``stream``."""
        return Path(self.input).stem if self.input not in (None, "-") else "stream"

    def open(self, *, paced: bool = False,
             wanted: Callable[[], int] | None = None) -> tuple[int, Iterator[np.ndarray]]:
        """(sample rate, chunks of mono samples); ``paced`` reads a file at its own pace; standard input is read
        ``wanted()`` samples at a time where that is given (see :func:`~prosody.live.converter.byte_chunks`)."""
        if self.mic:
            return microphone_chunks(sample_rate_hz=self.mic_rate)
        if self.input == "-":
            return byte_chunks(sys.stdin.buffer, raw=self.raw, source="<stdin>", wanted=wanted)
        assert self.input is not None
        return file_chunks(self.input, realtime=self.realtime or paced)


@dataclass(frozen=True)
class StreamOptions:
    """What a live session does with its frames.

    Parameters
    ----------
    output : str or None
        ``"-"``: one JSON line per frame on standard output as each is ready; a ``.jsonl`` file: the same lines,
        renamed over the file when the stream ends; another file (.fap, .csv, .json, .bvh, .livelink.csv):
        written when the stream ends. None: no output.
    format : str or None
        Format of the output file, overriding its ending.
    listen : str or None
        ``HOST:PORT`` to serve the face page and the frames' WebSocket on.
    allow_origin : tuple of str
        Other pages allowed to open the stream of ``listen``.
    livelink, vmc : tuple of str
        ``HOST[:PORT]`` targets of Live Link Face packets and of the VMC protocol.
    livelink_subject : str
        The subject name of the Live Link stream.
    vmc_perfect_sync : bool
        Send the 52 ARKit blendshapes over VMC instead of VRM's presets.
    loop : bool
        Play a file again and again at its own pace until stopped.
    lookahead_ms : float
        Audio after each frame that the frame may use.
    converter : mapping
        Further keyword arguments of :class:`~prosody.live.converter.LiveConverter` (condition, model, seed,
        eyebrow_rule, gains, disabled, live_lips, expression, expressivity, fps, f0_floor_hz, f0_ceiling_hz).
    face : PhotoHead, optional
        The head the page of ``listen`` shows: a person's from a photo (:mod:`prosody.head.photo`) instead of
        the 3D head.
    """

    output: str | None = None
    format: str | None = None
    listen: str | None = None
    allow_origin: tuple[str, ...] = ()
    livelink: tuple[str, ...] = ()
    livelink_subject: str = "prosody"
    vmc: tuple[str, ...] = ()
    vmc_perfect_sync: bool = False
    loop: bool = False
    lookahead_ms: float = DEFAULT_LOOKAHEAD_MS
    converter: Mapping[str, Any] = field(default_factory=dict)
    face: Any = None

    @property
    def sending(self) -> bool:
        return bool(self.livelink or self.vmc)

    def make_converter(self, rate: int) -> LiveConverter:
        """A fresh converter of these options for audio at ``rate`` Hz."""
        return LiveConverter(rate, lookahead_ms=self.lookahead_ms, **self.converter)


def check_session(options: StreamOptions, source: AudioSource | None,
                  flag: Callable[[str], str] = python_name) -> None:
    """Refuse a session that cannot run as asked, before anything listens or reads.

    Parameters
    ----------
    options : StreamOptions
        The session's options.
    source : AudioSource or None
        Its audio (None: only the pages' microphones, through ``listen``).
    flag : callable
        How a message names an option (``mic``, ``input``, ``listen``, ...): Python's keyword by default.

    Raises
    ------
    ConfigError
        A combination that would do something other than asked, or nothing at all.
    """
    _check_sources_and_sinks(options, source, flag)
    _check_output(options, source, flag)
    if options.allow_origin and options.listen is None:
        raise ConfigError(f"{flag('allow_origin')} names pages allowed to open the stream of {flag('listen')}; "
                          f"give {flag('listen')} too", parameter="allow_origin")
    if options.allow_origin:
        from ..net import normalize_origin

        for origin in options.allow_origin:
            normalize_origin(origin)


def _check_sources_and_sinks(options: StreamOptions, source: AudioSource | None, flag: Callable[[str], str]) -> None:
    """Something to read and somewhere to send it, and each link's option only with its link."""
    if source is None and options.listen is None:
        raise ConfigError(f"give {flag('input')} (a file, or - for standard input), {flag('mic')}, or "
                          f"{flag('listen')} to serve the page for browsers' microphones")
    if options.output is None and options.listen is None and not options.sending:
        raise ConfigError(f"give {flag('output')} OUT (- for one JSON line per frame on standard output), "
                          f"{flag('listen')}, {flag('livelink')} or {flag('vmc')}")
    if options.sending and source is None:
        raise ConfigError(f"{flag('livelink')} and {flag('vmc')} send the frames of an input: give a file, - or "
                          f"{flag('mic')}")
    if options.vmc_perfect_sync and not options.vmc:
        raise ConfigError(f"{flag('vmc_perfect_sync')} chooses what {flag('vmc')} sends; give {flag('vmc')} too",
                          parameter="vmc_perfect_sync")
    if options.livelink_subject != "prosody" and not options.livelink:
        raise ConfigError(f"{flag('livelink_subject')} names the stream of {flag('livelink')}; give "
                          f"{flag('livelink')} too", parameter="livelink_subject")


def _check_output(options: StreamOptions, source: AudioSource | None, flag: Callable[[str], str]) -> None:
    """Pacing that fits the source, and an output file that can be written as asked (its format known now)."""
    paced = options.loop or (source is not None and source.realtime)
    if paced and (source is None or source.arrives_live):
        what = f"{flag('loop')} plays a file again" if options.loop else f"{flag('realtime')} paces a file"
        raise ConfigError(f"{what}; standard input and microphones arrive at their own pace")
    if options.loop and options.output not in (None, "-"):
        raise ConfigError(f"{flag('loop')} never ends, so {flag('output')} would never be written: watch it with "
                          f"{flag('listen')}, or send it with {flag('livelink')} or {flag('vmc')}")
    if source is None and options.output is not None:
        raise ConfigError(f"{flag('output')} writes the frames of the input; with {flag('listen')} alone, each "
                          "browser gets the frames of its own microphone")
    if options.format is not None and options.output in (None, "-"):
        raise ConfigError(f"{flag('format')} names the format of an output file; {flag('output')} - always writes "
                          "JSON lines")
    if options.output not in (None, "-") and not (str(options.output).lower().endswith(".jsonl")
                                                   and options.format is None):
        # the format of a file written when the stream ends is known now, not after the whole session
        from ..outputs import MOTION_FORMATS, format_for

        chosen = format_for(options.output, options.format)
        if chosen not in MOTION_FORMATS:
            raise ConfigError(f"{flag('output')} {options.output}: a live stream writes motion "
                              f"({', '.join(MOTION_FORMATS)}, or JSON lines to a .jsonl file), not {chosen}")


@dataclass
class _Pass:
    """One pass over the source: its converter and sample rate."""

    converter: LiveConverter
    rate: int


@dataclass
class StreamResult:
    """What a session did: frames given out, at what rate, and how it ended."""

    frames: int
    fps: float
    lookahead_frames: int
    interrupted: bool
    passes: int
    faps: tuple[int, ...]
    senders: list = field(default_factory=list)
    clients_served: int = 0


class StreamSession:
    """One live session (``prosody stream``): read a source, convert, and feed every sink until it ends.

    Parameters
    ----------
    options : StreamOptions
        What to do with the frames.
    report : callable, optional
        Called with each line a person would want to read (the server's address, a file waiting for its page);
        default: nothing is said.
    warn : callable, optional
        Called with each warning (a link whose tool is not listening); default: ``report``.
    """

    def __init__(self, options: StreamOptions, *, report: Callable[[str], None] | None = None,
                 warn: Callable[[str], None] | None = None) -> None:
        self.options = options
        self.report: Callable[[str], None] = report or (lambda line: None)
        self.warn = warn or self.report
        self._requested: queue.SimpleQueue[Expressivity] = queue.SimpleQueue()  # a page's controls, for the reader
        self.server: Any = None

    def run(self, source: AudioSource | None, sinks: Sequence[Sink] = (),
            flag: Callable[[str], str] = python_name) -> StreamResult:
        """Run until the source ends, or Ctrl-C / SIGTERM (the last frames flushed); None: serve pages only.

        Parameters
        ----------
        source : AudioSource or None
            The audio; None serves the page of ``listen``, each browser streaming its own microphone.
        sinks : sequence of callables
            Each is called with every list of frames that became final, besides the options' own outputs.
        flag : callable
            How messages name options (see :func:`check_session`).

        Returns
        -------
        StreamResult
            Frames given out and how the session ended.
        """
        options = self.options
        check_session(options, source, flag)
        if source is None:
            options.make_converter(PROBE_RATE_HZ)  # the converter's options are checked before anything listens
            return self._serve_only()
        made: list[LiveConverter] = []  # the converter says how much audio its next frame waits for
        rate, chunks = source.open(paced=options.loop, wanted=lambda: made[0].samples_wanted())
        converter = options.make_converter(rate)
        made.append(converter)
        senders = self._link_senders(converter.fps)
        with contextlib.ExitStack() as running:
            for sender in senders:
                running.callback(sender.close)
            if options.listen is not None:
                self._start_server(reading=True)
                running.callback(self.server.close)
                if not source.arrives_live and (source.realtime or options.loop) and not self._wait_for_page():
                    return StreamResult(0, converter.fps, converter.lookahead_frames, True, 0,
                                        tuple(converter.faps), senders)
            return self._convert(source, rate, chunks, converter, senders, list(sinks), running)

    # the parts of a session ---------------------------------------------------------------------------------
    def _link_senders(self, fps: float) -> list:
        """The UDP senders (Live Link, VMC), their targets resolved before anything starts."""
        from .senders import LinkSender

        options, senders = self.options, []
        if options.livelink:
            senders.append(LinkSender("livelink", options.livelink, fps=fps, subject=options.livelink_subject,
                                      report=self.warn))
        if options.vmc:
            senders.append(LinkSender("vmc", options.vmc, fps=fps, perfect_sync=options.vmc_perfect_sync,
                                      report=self.warn))
        return senders

    def _start_server(self, *, reading: bool) -> None:
        from ..net import parse_address
        from .server import FrameServer

        options = self.options
        host, port = parse_address(options.listen or "")
        self.server = FrameServer(host, port, make_converter=options.make_converter,
                                  allow_origins=list(options.allow_origin), report=self.report,
                                  expressivity=options.converter.get("expressivity"),
                                  on_expressivity=self._requested.put if reading else None, face=options.face)
        self.server.start()
        self.report(f"serving the face at {self.server.url} (frames over a WebSocket on the same address)")

    def _wait_for_page(self) -> bool:
        """A file played at its own pace is for watching: it starts when the first page is there to see it."""
        self.report("the file starts when the first page connects (Ctrl-C to stop)")
        try:
            while not self.server.first_client.wait(0.2):
                pass
        except KeyboardInterrupt:
            self.server.close()
            self.report("stopped before any page connected")
            return False
        return True

    def _serve_only(self) -> StreamResult:
        from ..net import serve_until_interrupted

        self._start_server(reading=False)
        serve_until_interrupted(self.server.close)
        self.report(f"stopped after serving {self.server.clients_served} client(s)")
        return StreamResult(0, 0.0, 0, True, 0, (), [], self.server.clients_served)

    def _convert(self, source: AudioSource, rate: int, chunks: Iterator[np.ndarray], converter: LiveConverter,
                 senders: list, sinks: list[Sink], running: contextlib.ExitStack) -> StreamResult:
        options, server = self.options, self.server
        to_stdout = options.output == "-"
        to_file = options.output not in (None, "-")
        lines_to_file = to_file and str(options.output).lower().endswith(".jsonl") and options.format is None
        recorder = FrameRecorder(converter.faps) if to_file and not lines_to_file else None
        # JSON lines go to a file as they come (renamed over the output only when the stream ends well)
        output = str(options.output)
        lines = running.enter_context(atomic_write(output, newline="\n")) if lines_to_file else None
        outlets: list[Sink] = [*([server.publish] if server is not None else []),
                               *(sender.send for sender in senders), *sinks]
        if to_stdout or lines is not None:
            write = sys.stdout.write if to_stdout else lines.write  # type: ignore[union-attr]

            def write_lines(new: list[LiveFrame]) -> None:
                write("".join(frame.to_json() + "\n" for frame in new))
                if to_stdout:
                    sys.stdout.flush()

            outlets.append(write_lines)
        elif recorder is not None:
            outlets.append(recorder.add)
        count = 0

        def emit(new: list[LiveFrame]) -> None:
            nonlocal count
            if new:
                count += len(new)
                for outlet in outlets:
                    outlet(new)

        if source.arrives_live:  # programs wait for this line before they send
            self.report(f"reading {'the microphone' if source.mic else 'standard input'} at {rate} Hz (Ctrl-C to stop)")
        passes = 0
        current = _Pass(converter, rate)  # the converter and rate of this pass of the file

        def consume(samples: np.ndarray) -> None:
            while not self._requested.empty():
                current.converter.set_expressivity(self._requested.get())
            if server is not None:
                server.publish_audio(samples, current.rate)
            emit(current.converter.push(samples))

        while True:
            interrupted = read_until_stopped(chunks, consume)
            emit(converter.finish())
            passes += 1
            if interrupted or not options.loop:
                break
            rate, chunks = source.open(paced=True)  # the file again, from a fresh start
            converter = options.make_converter(rate)
            current = _Pass(converter, rate)
            if server is not None:  # the controls a page may have changed meanwhile
                converter.set_expressivity(server.expressivity)
                server.restart_audio()
        if recorder is not None:
            from ..outputs import write_stream

            write_stream(recorder.stream(fps=converter.fps, name=source.name), output, options.format)
        return StreamResult(count, converter.fps, converter.lookahead_frames, interrupted, passes,
                            tuple(converter.faps), senders, server.clients_served if server is not None else 0)


def read_until_stopped(chunks: Iterable[np.ndarray], consume: Callable[[np.ndarray], object]) -> bool:
    """Feed every chunk to ``consume`` until the chunks end or Ctrl-C / SIGTERM arrives; True if stopped.

    The signal only breaks off a wait for input: a chunk being processed is finished first, so the converter
    is never left half-way through a frame and the last frames can be flushed.
    """
    state = {"reading": False, "stopped": False}

    def stop(signum, frame) -> None:
        state["stopped"] = True
        if state["reading"]:
            raise KeyboardInterrupt

    previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        for sig in previous:
            signal.signal(sig, stop)
    except ValueError:  # not the main thread: signals stay as they are
        previous = {}
    iterator = iter(chunks)
    try:
        while not state["stopped"]:
            state["reading"] = True
            try:
                samples = next(iterator)
            except (StopIteration, KeyboardInterrupt):
                break
            finally:
                state["reading"] = False
            consume(samples)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return state["stopped"]
