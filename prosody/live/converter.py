"""Live conversion: audio that is still arriving in, FAP frames out as soon as each is known.

:class:`LiveConverter` is the one entry point (the ``prosody stream`` command is a shell over it): push audio
in pieces of any size, get back the frames that became final. Frame ``k`` uses audio up to
``k / fps + lookahead`` and nothing later, so its latency is the look-ahead plus half an analysis window
(about 34 ms) plus the time to compute it.
"""

from __future__ import annotations

import array
import json
import math
import os
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from audio_features.pcm import PcmDecoder, PcmFormat, read_wav_header
from audio_features.streaming import StreamingAnalyser

from ..errors import ConfigError
from ..fap.stream import FapStream
from ..fap.table import EYEBROW_FAPS, HEAD_FAPS, PROSODY_FAPS
from ..motion.conditions import Condition
from ..motion.expressivity import BrowShaper, Expressivity, HeadShaper
from ..motion.face.expressions import (
    ExpressionSegment,
    add_brow_raises,
    expressions_at,
    mix_with_lips,
    parse_expressions,
)
from ..motion.face.lips import LIP_FAPS, shape_fap_values
from ..motion.heads.live import DEFAULT_LOOKAHEAD_MS, LiveHeadModel, LivePerlin, live_brows
from ..motion.limits import limit_frame
from ..motion.model_files import MODELS_DIR, read_model_json
from ..motion.settings import (
    CHANNELS,
    AnalysisSettings,
    ChannelSettings,
    LiveFields,
    MotionSettings,
    settings_groups,
)

if TYPE_CHECKING:  # the keywords' types, for a type checker
    from typing_extensions import Unpack

#: Shipped live head models by the look-ahead they read, in ms.
LIVE_MODELS_DIR = MODELS_DIR
SHIPPED_LOOKAHEADS_MS = (0, 100, 200, 300, 500)


def shipped_live_model_path(lookahead_ms: float) -> Path:
    return LIVE_MODELS_DIR / f"live_head_{int(lookahead_ms)}ms.json"


#: The offline head models' names (``convert --model``) that have no live form, and why.
OFFLINE_ONLY_MODELS = {
    "arx": "Zavala Chmelicka's ARX model is fitted on whole recordings",
    "pad": "Jia et al.'s gestures take a whole prosodic word, which a stream has not heard yet",
    "pad-random": "Jia et al.'s random baseline takes a whole prosodic word, which a stream has not heard yet",
}


def live_head_model(model: LiveHeadModel | str | os.PathLike[str] | None, *, lookahead_ms: float) -> LiveHeadModel:
    """The live head model to stream with: the given one, a file, or (None or ``"prosodic"``, the name ``convert``
    gives the default head) the shipped model that reads the most look-ahead within ``lookahead_ms``. The other
    names of ``convert --model`` are refused with the reason (:data:`OFFLINE_ONLY_MODELS`)."""
    if isinstance(model, LiveHeadModel):
        return model
    if model is None or os.fspath(model) == "prosodic":
        usable = [ms for ms in SHIPPED_LOOKAHEADS_MS if ms <= lookahead_ms + 1e-9]
        if not usable:
            raise ConfigError(f"lookahead_ms must be >= 0, got {lookahead_ms!r}", parameter="lookahead_ms")
        return LiveHeadModel.load(shipped_live_model_path(max(usable)))
    if os.fspath(model) in OFFLINE_ONLY_MODELS:
        raise ConfigError(f"model={os.fspath(model)}: {OFFLINE_ONLY_MODELS[os.fspath(model)]}, so it is not "
                          "offered live; stream with the live head (prosodic, the default) or a model from "
                          "'prosody train --kind live'", parameter="model")
    return LiveHeadModel.from_dict(read_model_json(model), source=str(model))


@dataclass(frozen=True)
class LiveFrame:
    """One output frame: its index, time, and FAP -> value (FAP units) of the channels that are on."""

    frame: int
    time_s: float
    faps: dict[int, float]

    def to_json(self) -> str:
        """``{"frame": k, "time_s": t, "faps": {"31": v, ...}}`` on one line."""
        return json.dumps({"frame": self.frame, "time_s": round(self.time_s, 6),
                           "faps": {str(fap): round(value, 3) for fap, value in self.faps.items()}},
                          separators=(",", ":"))


class LiveConverter:
    """Audio in, FAP frames out, causally.

    Parameters
    ----------
    sample_rate_hz : int in [8000, 768000]
        Rate of the audio that will be pushed (mono float, full scale +-1).
    condition : {"speech", "random", "none"} or Condition
        ``speech``: live brows (accent rule by default) and the live head; ``random``: Perlin noise;
        ``none``: still.
    lookahead_ms : float >= 0, in ms
        Audio after each frame that the frame may use (whole frames of it: never more than asked).
    live_lips : bool
        Lips from the live acoustic mouth model (the same in every condition; the shipped model with the most
        look-ahead within ``lookahead_ms``: 0 or 100 ms). The visemes need whole phones and their neighbours,
        so they are not offered live.
    expression : str or sequence of ExpressionSegment, optional
        A facial expression as ``convert``'s (``NAME:INTENSITY``, a timed CSV file, or segments), mixed with the
        lips and under the brow raises frame by frame exactly as offline: each frame's blend needs only its time.
    analysis : AnalysisSettings, optional
        How the stream is analysed; or its fields as keywords (below).
    motion : MotionSettings, optional
        The live head model (a :class:`LiveHeadModel` or its file; the shipped one for the look-ahead when
        omitted), the seed of the head and of the random condition, the brow rule, and the expressivity
        controls, exactly as offline (they look at no future frame; :meth:`set_expressivity` changes them while
        streaming); or its fields as keywords.
    channels : ChannelSettings, optional
        Gains and channels left out, as :func:`prosody.jobs.pipeline.convert`'s; or its fields as keywords.
    **fields
        Any field of the three groups above by its name, overriding that group's: ``fps``, ``f0_floor_hz``,
        ``f0_ceiling_hz``, ``workers`` (unused: a live stream is analysed as it comes, in this process);
        ``model``, ``seed``, ``eyebrow_rule``, ``expressivity``; ``gains``, ``disabled``.
        Typed by :class:`~prosody.motion.settings.LiveFields`.

    Examples
    --------
    >>> t = np.arange(32000) / 16000
    >>> converter = LiveConverter(16000)
    >>> frames = converter.push(0.5 * np.sin(2 * np.pi * 150 * t)) + converter.finish()
    >>> len(frames), sorted(frames[0].faps)[:8]
    (60, [3, 4, 5, 6, 7, 8, 9, 10])
    """

    def __init__(self, sample_rate_hz: int, *, condition: Condition | str = Condition.SPEECH_DRIVEN,
                 lookahead_ms: float = DEFAULT_LOOKAHEAD_MS, live_lips: bool = True,
                 expression: str | Sequence[ExpressionSegment] | None = None,
                 analysis: AnalysisSettings = AnalysisSettings(), motion: MotionSettings = MotionSettings(),
                 channels: ChannelSettings = ChannelSettings(), **fields: Unpack[LiveFields]) -> None:
        analysis, motion, _, channels = settings_groups("LiveConverter", fields, analysis=analysis, motion=motion,
                                                        channels=channels, taking=("analysis", "motion", "channels"))
        channels.check_leaves_output(lips=bool(live_lips), face_layer=bool(expression))
        chosen = condition if isinstance(condition, Condition) else Condition.parse(condition)
        if chosen is Condition.GROUND_TRUTH:
            raise ConfigError("recorded motion (condition truth) has no live form; choose speech, random or none")
        if not (isinstance(lookahead_ms, (int, float)) and math.isfinite(lookahead_ms) and 0 <= lookahead_ms <= 2000):
            raise ConfigError(f"lookahead_ms must be a number in [0, 2000], got {lookahead_ms!r}",
                              parameter="lookahead_ms")
        self.condition = chosen
        self.analyser = StreamingAnalyser(sample_rate_hz, **analysis.as_keywords())
        self.fps = self.analyser.fps
        # floored: 20 ms at 30 fps reads no frame ahead, not one (33 ms); 1e-9 keeps 100 ms at 3 frames
        self.lookahead_frames = int(math.floor(lookahead_ms / 1000 * self.fps + 1e-9))
        self._gain = {fap: channels.gain(name) for name, faps in CHANNELS.items() for fap in faps}
        off = channels.disabled_faps()
        self._mouth = None
        if live_lips and not set(LIP_FAPS) <= off:
            from ..motion.face.mouth_model import SHIPPED_LIVE_MOUTH_MS, LiveMouthModel, live_mouth_path

            usable = max(ms for ms in SHIPPED_LIVE_MOUTH_MS if ms <= lookahead_ms + 1e-9)
            self._mouth = LiveMouthModel.load(live_mouth_path(usable)).start(sample_rate_hz, fps=self.analyser.fps)
        # an expression over the frames (constant, or timed: each frame's blend needs only its own time)
        self._expression = parse_expressions(expression) if isinstance(expression, str) else list(expression or ())
        shown = set(expressions_at(self._expression, np.zeros(1))) if self._expression else set()
        produced = set(LIP_FAPS if self._mouth is not None else ()) | set(PROSODY_FAPS) | shown
        self.faps = tuple(sorted(fap for fap in produced if fap not in off))
        if not self.faps:
            raise ConfigError("every channel is off: the frames would be empty")
        self._head = self._brows = self._perlin = None
        if chosen is Condition.SPEECH_DRIVEN:
            head_model = live_head_model(motion.model, lookahead_ms=lookahead_ms)
            if head_model.fps_ != self.fps:
                raise ConfigError(f"the live head model runs at {head_model.fps_:g} fps; stream at fps="
                                  f"{head_model.fps_:g} or train a live model at {self.fps:g} fps", parameter="fps")
            self._head = head_model.start(lookahead=self.lookahead_frames, seed=motion.seed)
            self._brows = live_brows(motion.eyebrow_rule, fps=self.fps, lookahead=self.lookahead_frames)
        elif chosen is Condition.RANDOM:
            self._perlin = LivePerlin(fps=self.fps, seed=motion.seed)
        self._shapers: tuple[HeadShaper, BrowShaper] | None = None
        if chosen is not Condition.NO_PROSODY:
            controls = motion.expressivity or Expressivity()
            self._shapers = (HeadShaper(controls, fps=self.fps), BrowShaper(controls, fps=self.fps))
        self._next = 0
        self.finished = False
        self._pending: list[np.ndarray] = []
        self._pending_samples = 0

    @property
    def expressivity(self) -> Expressivity:
        """The expressivity controls in use (neutral for the still condition)."""
        return self._shapers[0].expressivity if self._shapers is not None else Expressivity()

    def set_expressivity(self, expressivity: Expressivity) -> None:
        """Change the expressivity controls from the next frame given out on (while streaming).

        Parameters
        ----------
        expressivity : Expressivity
            The new controls (see :mod:`prosody.motion.expressivity`).
        """
        if not isinstance(expressivity, Expressivity):
            raise ConfigError(f"expected an Expressivity, got {expressivity!r}")
        if self._shapers is not None:
            for shaper in self._shapers:
                shaper.set(expressivity)

    @property
    def latency_s(self) -> float:
        """Audio after a frame's time needed before the frame is given out (look-ahead and analysis window)."""
        return self.lookahead_frames / self.fps + self.analyser.latency_s()

    def _frames(self, f0: np.ndarray, energy: np.ndarray, *, final: bool) -> list[LiveFrame]:
        values: list[dict[int, float]] = []
        if self.condition is Condition.SPEECH_DRIVEN:
            assert self._head is not None and self._brows is not None
            brows, heads = [], []
            for f, e in zip(f0.tolist(), energy.tolist(), strict=True):
                brow, head = self._brows.push(f, e), self._head.push(f, e)
                if brow is not None:
                    brows.append(brow)
                    heads.append(head)
            if final:
                brows += self._brows.finish()
                heads += self._head.finish()
            for brow, head in zip(brows, heads, strict=True):
                assert head is not None
                values.append({**dict.fromkeys(EYEBROW_FAPS, brow),
                               **{fap: float(head[axis]) for axis, fap in enumerate(HEAD_FAPS)}})
        else:
            for k in range(self._next, self._next + f0.size):
                values.append(self._perlin.frame(k) if self._perlin is not None
                              else dict.fromkeys(PROSODY_FAPS, 0.0))
        if self._shapers is not None:
            head_shaper, brow_shaper = self._shapers
            for value in values:
                pose = head_shaper.step(np.array([value[fap] for fap in HEAD_FAPS]))
                value.update({fap: float(pose[axis]) for axis, fap in enumerate(HEAD_FAPS)})
                value.update(dict.fromkeys(EYEBROW_FAPS, brow_shaper.step(value[EYEBROW_FAPS[0]])))
        frames = []
        for value in values:
            k = self._next
            self._next += 1
            if self._mouth is not None:
                value.update(shape_fap_values(*self._mouth.values(k)))
            faps = {fap: value[fap] * self._gain[fap] for fap in self.faps if fap in value}
            if self._expression:
                faps = self._with_expression(faps, k / self.fps)
            frames.append(LiveFrame(k, k / self.fps, limit_frame(faps)))
        return frames

    def _with_expression(self, faps: dict[int, float], time_s: float) -> dict[int, float]:
        """One frame's FAPs with the expression mixed in as offline (:class:`prosody.motion.face.layer.FaceLayer`):
        by Jia et al.'s Eq. 14 with the lips, under the prosodic brow raises, alone elsewhere."""
        shown = {fap: curve for fap, curve in expressions_at(self._expression, np.array([time_s])).items()
                 if fap in self.faps}
        brows = {fap: np.array([faps[fap]]) for fap in shown if 31 <= fap <= 36 and fap in faps}
        lips = {fap: np.array([value]) for fap, value in faps.items() if fap in LIP_FAPS}
        mixed = mix_with_lips(lips, {fap: curve for fap, curve in shown.items() if fap not in brows})
        mixed.update(add_brow_raises({fap: shown[fap] for fap in brows}, brows))
        return {**faps, **{fap: float(curve[0]) for fap, curve in mixed.items()}}

    def push(self, samples: np.ndarray) -> list[LiveFrame]:
        """Add audio.

        Parameters
        ----------
        samples : numpy.ndarray
            Mono float samples at the converter's sample rate, full scale +-1, any number of them.

        Returns
        -------
        list of LiveFrame
            The frames that became final, possibly none.
        """
        if self.finished:
            raise ConfigError("push() after finish(): make a new LiveConverter for new audio")
        # audio that completes no frame is kept until some does (a pipe gives 10 ms pieces, a frame needs 33 ms):
        # the frames and the moment each is given out are the same, the work per piece a third
        samples = self.analyser.checked(samples, held=self._pending_samples)
        self._pending.append(samples)
        self._pending_samples += samples.size
        if self.analyser.samples_received + self._pending_samples < self.analyser.samples_needed():
            return []
        return self._frames(*self._take_pending(), final=False)

    def samples_wanted(self) -> int:
        """Samples still to come before the next frame can be analysed (at least 1): what a reader that waits for
        whole frames reads next.

        Returns
        -------
        int
        """
        return max(1, self.analyser.samples_needed() - self.analyser.samples_received - self._pending_samples)

    def _take_pending(self) -> tuple[np.ndarray, np.ndarray]:
        """Push the audio kept so far to the analysis and the mouth: the F0 and energy of the frames it completes."""
        samples = self._pending[0] if len(self._pending) == 1 else np.concatenate(self._pending)
        self._pending, self._pending_samples = [], 0
        f0, energy = self.analyser.push(samples)
        if self._mouth is not None:
            self._mouth.push(samples)
        return f0, energy

    def finish(self) -> list[LiveFrame]:
        """The audio has ended.

        Returns
        -------
        list of LiveFrame
            The frames still waiting for their look-ahead (none after the first call).
        """
        if self.finished:
            return []
        self.finished = True
        early = self._frames(*self._take_pending(), final=False) if self._pending else []
        f0, energy = self.analyser.finish()
        if self._mouth is not None:
            self._mouth.finish()
        return early + self._frames(f0, energy, final=True)


class FrameRecorder:
    """The frames of a whole stream, kept at 8 bytes a value (about 6 MB an hour at 30 fps), for a file
    written when the stream ends."""

    def __init__(self, faps: Iterable[int]) -> None:
        self.columns = {fap: array.array("d") for fap in faps}
        self.count = 0

    def add(self, frames: list[LiveFrame]) -> None:
        for frame in frames:
            for fap, column in self.columns.items():
                column.append(frame.faps[fap])
        self.count += len(frames)

    def stream(self, *, fps: float, name: str) -> FapStream:
        curves = {fap: np.array(column, dtype=float) for fap, column in self.columns.items()}
        return FapStream.from_curves(curves, fps=fps, name=name, n_frames=self.count)


# audio sources --------------------------------------------------------------------------------------------
#: Samples read at a time from a file (10 ms at 16 kHz).
FILE_BLOCK_S = 0.01


def file_chunks(path: str | os.PathLike[str], *, realtime: bool = False,
                block_s: float = FILE_BLOCK_S) -> tuple[int, Iterator[np.ndarray]]:
    """``(sample rate, chunks)`` of an audio file read in blocks, mixed to mono; with ``realtime``, each
    block is given no sooner than the time it ends at (a demo of live input from a file)."""
    import soundfile

    from audio_features.audio import check_shape, open_sound_file, read_blocks

    sound = open_sound_file(path)
    check_shape(sound.frames, source=str(path), sample_rate_hz=sound.samplerate)
    rate = int(sound.samplerate)
    block = max(1, int(round(block_s * rate)))

    def chunks() -> Iterator[np.ndarray]:
        start = time.monotonic()
        done = 0
        with sound:
            try:
                for data in read_blocks(sound, block):
                    done += data.shape[0]
                    if realtime:
                        delay = start + done / rate - time.monotonic()
                        if delay > 0:
                            time.sleep(delay)
                    yield data[:, 0] if data.shape[1] == 1 else data.mean(axis=1)
            except (soundfile.SoundFileError, RuntimeError) as error:
                from audio_features.errors import AudioLoadError

                raise AudioLoadError(f"{path}: decoding failed ({error})") from None

    return rate, chunks()


class IncompleteSampleWarning(UserWarning):
    """A byte stream ended inside a sample frame; the incomplete sample was dropped."""


def byte_chunks(stream, *, raw: PcmFormat | None = None, source: str = "<stdin>",
                read_size: int = 4096, wanted: Callable[[], int] | None = None) -> tuple[int, Iterator[np.ndarray]]:
    """``(sample rate, chunks)`` of audio arriving on a binary stream: a WAV stream (its header read
    first; a length the header does not know is read to the end) or, with ``raw``, headerless samples.

    Chunks are given as soon as bytes arrive; with ``wanted`` (the samples its reader can use next, as
    :meth:`LiveConverter.samples_wanted` says), each chunk is that many samples, read in one wait (fewer at the
    end): a pipe that delivers 10 ms pieces wakes the reader once a frame, when the frame can be made, not three
    times."""
    import warnings

    read = getattr(stream, "read1", stream.read)
    limit: int | None = None
    if raw is None:
        raw, limit = read_wav_header(stream.read, source=source)
    decoder = PcmDecoder(raw)

    def chunks() -> Iterator[np.ndarray]:
        remaining = limit
        while remaining is None or remaining > 0:
            if wanted is None:
                size = read_size
            else:  # whole sample frames, at most a second's, so a slow source never holds a long wait
                count = min(max(1, wanted()), raw.sample_rate_hz)
                size = max(1, count * raw.frame_bytes - decoder.pending_bytes)
            size = size if remaining is None else min(size, remaining)
            data = read(size) if wanted is None else stream.read(size)
            if not data:
                break
            if remaining is not None:
                remaining -= len(data)
            samples = decoder.decode(data)
            if samples.size:
                yield samples
        if decoder.pending_bytes:
            warnings.warn(f"{source}: the stream ended inside a sample; its last {decoder.pending_bytes} byte(s) "
                          "were dropped", IncompleteSampleWarning, stacklevel=2)

    return raw.sample_rate_hz, chunks()


def microphone_chunks(*, sample_rate_hz: int = 16000,
                      block_s: float = FILE_BLOCK_S) -> tuple[int, Iterator[np.ndarray]]:
    """``(sample rate, chunks)`` from the default input device (needs the ``sounddevice`` package)."""
    try:
        import sounddevice
    except ImportError:
        raise ConfigError("--mic needs the sounddevice package: pip install 'visual-prosody[mic]'") from None
    except OSError:  # the package is there, the system's PortAudio library is not
        raise ConfigError("--mic needs the system's PortAudio library: apt install libportaudio2 (Debian, "
                          "Ubuntu), brew install portaudio (macOS)") from None
    import queue

    blocks: queue.Queue[np.ndarray] = queue.Queue()

    def callback(indata, frames, time_info, status) -> None:  # runs on PortAudio's thread
        blocks.put(indata[:, 0].astype(np.float64).copy())

    try:  # opened here, so that a machine without a microphone is told before anything starts
        stream = sounddevice.InputStream(samplerate=sample_rate_hz, channels=1, dtype="float32",
                                         blocksize=max(1, int(block_s * sample_rate_hz)), callback=callback)
    except (sounddevice.PortAudioError, ValueError) as error:
        raise ConfigError(f"--mic: no microphone to read at {sample_rate_hz} Hz ({str(error).strip()}); "
                          "plug one in, or choose another rate with --mic-rate") from None

    def chunks() -> Iterator[np.ndarray]:
        with stream:
            while True:
                yield blocks.get()

    return sample_rate_hz, chunks()
