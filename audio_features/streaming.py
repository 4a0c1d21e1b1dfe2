"""Acoustic features of live audio, frame by frame, each frame computed once and never revised.

:class:`StreamingAnalyser` runs the same Praat analyses as :func:`audio_features.extract_features` (pitch by
autocorrelation, intensity in dB) on a short stretch of audio ending with each frame's own analysis window,
so frame ``k`` is known as soon as the audio up to ``k / fps`` plus half a window (32 ms for the intensity's
64 ms window) has arrived. Its results depend on the audio only, never on how the audio was cut into pieces
when it arrived: a pipe that delivers 17 samples at a time gives the same frames as one ``push`` of the whole
file.

Two things differ from the whole-file analysis, because the future is not known:

- Praat's pitch path finder sees ``context_s`` of audio before the frame and none after it;
- Praat's voicing decision is relative to the loudest sample of the sound; live, that is the loudest sample
  of the last minute (:data:`PEAK_WINDOW_S`), so one loud knock is forgotten after a minute.

:class:`CausalF0Bridge` is the causal counterpart of :func:`audio_features.condition_f0`, and
:class:`RunningMedian` gives a speaker's median pitch or level from the frames seen so far, in constant memory.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from .analysis import (
    ENERGY_FLOOR_DB,
    INTENSITY_PERIODS_PER_WINDOW,
    PITCH_PERIODS_PER_WINDOW,
    PITCH_SILENCE_THRESHOLD,
    _aligned_segment,
    _frames_on_steps,
    analysis_step,
)
from .audio import MAX_SAMPLE_RATE_HZ, MIN_SAMPLE_RATE_HZ
from .defaults import DEFAULT_F0_CEILING_HZ, DEFAULT_F0_FLOOR_HZ, DEFAULT_FPS, MIN_F0_FLOOR_HZ
from .errors import AudioLoadError, ParameterError
from .features import MAX_FPS, MIN_FPS, shape_preserving_spline

#: Audio before each frame given to Praat's pitch path finder, in s.
DEFAULT_CONTEXT_S = 0.25
#: The voicing decision is relative to the loudest sample of this much past audio, in s.
PEAK_WINDOW_S = 60.0
#: Length of the blocks whose peaks are remembered for :data:`PEAK_WINDOW_S`, in s.
_PEAK_BLOCK_S = 0.1


class StreamingAnalyser:
    """Praat F0 and intensity of audio that arrives piece by piece, one frame as soon as its audio is in.

    Parameters
    ----------
    sample_rate_hz : int in [8000, 768000]
        Samples per second of the incoming audio (mono, float, full scale +-1, taken as pascals).
    fps : float in (0, 1000]
        Frame rate of the grid; frame ``k`` is at ``k / fps`` s.
    f0_floor_hz, f0_ceiling_hz : float, 0 < floor < ceiling < Nyquist, in Hz
        Pitch search range, as in :func:`audio_features.extract_features`.
    intensity_min_pitch_hz : float > 0, in Hz
        Praat's To Intensity minimum pitch (its window is 6.4 periods).
    context_s : float in [0, 5], in s
        Audio before each frame that the pitch path finder sees.

    Examples
    --------
    A 200 Hz tone, pushed in pieces of 100 samples:

    >>> t = np.arange(16000) / 16000
    >>> tone = 0.5 * np.sin(2 * np.pi * 200 * t)
    >>> analyser = StreamingAnalyser(16000)
    >>> frames = [analyser.push(tone[i:i + 100]) for i in range(0, tone.size, 100)]
    >>> f0, energy = (np.concatenate(parts) for parts in zip(*frames, analyser.finish()))
    >>> f0.size, round(float(np.nanmedian(f0)))
    (30, 200)
    """

    def __init__(self, sample_rate_hz: int, *, fps: float = DEFAULT_FPS, f0_floor_hz: float = DEFAULT_F0_FLOOR_HZ,
                 f0_ceiling_hz: float = DEFAULT_F0_CEILING_HZ, intensity_min_pitch_hz: float = 100.0,
                 context_s: float = DEFAULT_CONTEXT_S) -> None:
        if isinstance(sample_rate_hz, bool) or not isinstance(sample_rate_hz, (int, np.integer)) or not (
                MIN_SAMPLE_RATE_HZ <= sample_rate_hz <= MAX_SAMPLE_RATE_HZ):
            raise ParameterError(f"sample_rate_hz must be a whole number in [{MIN_SAMPLE_RATE_HZ}, "
                                 f"{MAX_SAMPLE_RATE_HZ}], got {sample_rate_hz!r}")
        if not (isinstance(fps, (int, float)) and math.isfinite(fps) and MIN_FPS <= fps <= MAX_FPS):
            raise ParameterError(f"fps must be a number from {MIN_FPS:g} to {MAX_FPS:g}, got {fps!r}")
        if not MIN_F0_FLOOR_HZ <= f0_floor_hz < f0_ceiling_hz < sample_rate_hz / 2:
            raise ParameterError(f"need {MIN_F0_FLOOR_HZ:g} <= f0_floor_hz < f0_ceiling_hz < "
                                 f"{sample_rate_hz / 2:g} Hz (Nyquist), got floor {f0_floor_hz!r} and ceiling "
                                 f"{f0_ceiling_hz!r}", parameter=("f0_floor_hz", "f0_ceiling_hz"))
        if not intensity_min_pitch_hz > 0:
            raise ParameterError(f"intensity_min_pitch_hz must be > 0, got {intensity_min_pitch_hz!r}")
        if not 0 <= context_s <= 5:
            raise ParameterError(f"context_s must be in [0, 5] s, got {context_s!r}")
        self.sample_rate_hz = int(sample_rate_hz)
        self.fps = float(fps)
        self.f0_floor_hz, self.f0_ceiling_hz = float(f0_floor_hz), float(f0_ceiling_hz)
        self.intensity_min_pitch_hz = float(intensity_min_pitch_hz)
        self._dt, self._oversample = analysis_step(self.fps)
        self._pitch_window_s = PITCH_PERIODS_PER_WINDOW / self.f0_floor_hz
        self._intensity_window_s = INTENSITY_PERIODS_PER_WINDOW / self.intensity_min_pitch_hz
        self._margin_steps = int(round(context_s / self._dt))
        self._segments_of: tuple[int, tuple[tuple[int, int], tuple[int, int]]] | None = None
        self._buffer = np.zeros(0)
        self._buffer_start = 0  # absolute index of the buffer's first sample
        self._received = 0
        self._next_frame = 0
        self._finished = False
        self._peak_block = max(1, int(round(_PEAK_BLOCK_S * self.sample_rate_hz)))
        # (block index, peak) of the complete blocks that can still be the window's loudest, loudest first
        self._peak_blocks: deque[tuple[int, float]] = deque()
        self._peak_scanned = 0  # samples folded into the block peaks

    @property
    def frames_done(self) -> int:
        """Frames produced so far."""
        return self._next_frame

    @property
    def samples_received(self) -> int:
        return self._received

    def latency_s(self) -> float:
        """Audio needed after a frame's time before the frame can be computed (half the longer window).

        Returns
        -------
        float
            In s.
        """
        return 0.5 * max(self._pitch_window_s, self._intensity_window_s) + 2 / self.sample_rate_hz

    # the segments of one frame -------------------------------------------------------------------------
    def _segments(self, k: int) -> tuple[tuple[int, int], tuple[int, int]]:
        # asked for the next frame several times a push (is it ready, what to keep, how much audio to wait for)
        if self._segments_of is not None and self._segments_of[0] == k:
            return self._segments_of[1]
        segments = self._segments_at(k)
        self._segments_of = (k, segments)
        return segments

    def _segments_at(self, k: int) -> tuple[tuple[int, int], tuple[int, int]]:
        step = k * self._oversample
        first = max(0, step - self._margin_steps)
        pitch = _aligned_segment(first, step - first + 1, dt=self._dt, window_s=self._pitch_window_s,
                                 sample_rate_hz=self.sample_rate_hz)
        intensity = _aligned_segment(step, 1, dt=self._dt, window_s=self._intensity_window_s,
                                     sample_rate_hz=self.sample_rate_hz)
        return pitch, intensity

    def _read(self, start: int, length: int) -> np.ndarray:
        """Samples ``[start, start + length)``: zeros before the stream and past its end."""
        out = np.zeros(length)
        lo, hi = max(start, self._buffer_start), min(start + length, self._received)
        if hi > lo:
            out[lo - start:hi - start] = self._buffer[lo - self._buffer_start:hi - self._buffer_start]
        return out

    def _fold_peaks(self, end: int) -> None:
        """Fold the complete blocks before sample ``end`` into the remembered peaks and forget those older
        than :data:`PEAK_WINDOW_S`. Never past ``end``: a later frame's peak must not see its own future."""
        block = self._peak_block
        while self._peak_scanned + block <= min(end, self._received):
            index = self._peak_scanned // block
            chunk = self._read(self._peak_scanned, block)
            peak = float(np.max(np.abs(chunk), initial=0.0))
            # kept in falling order: a block no louder than a later one can never be the window's loudest
            while self._peak_blocks and self._peak_blocks[-1][1] <= peak:
                self._peak_blocks.pop()
            self._peak_blocks.append((index, peak))
            self._peak_scanned += block
        oldest = (end - int(PEAK_WINDOW_S * self.sample_rate_hz)) // block
        while self._peak_blocks and self._peak_blocks[0][0] < oldest:
            self._peak_blocks.popleft()

    def _peak_before(self, end: int) -> float:
        """The loudest sample of the :data:`PEAK_WINDOW_S` before sample ``end`` (a function of the audio
        only, however it arrived)."""
        self._fold_peaks(end)
        partial = self._read(self._peak_scanned, max(0, end - self._peak_scanned))
        return max(self._peak_blocks[0][1] if self._peak_blocks else 0.0,
                   float(np.max(np.abs(partial), initial=0.0)))

    def _frame(self, k: int) -> tuple[float, float]:
        import parselmouth

        (p_start, p_length), (i_start, i_length) = self._segments(k)
        sr = self.sample_rate_hz
        f0 = math.nan
        samples = self._read(p_start, p_length)
        segment_peak = float(np.max(np.abs(samples), initial=0.0))
        if segment_peak > 0:
            global_peak = max(self._peak_before(p_start + p_length), segment_peak)
            sound = parselmouth.Sound(samples, sampling_frequency=sr, start_time=p_start / sr)
            pitch = sound.to_pitch_ac(time_step=self._dt, pitch_floor=self.f0_floor_hz,
                                      pitch_ceiling=self.f0_ceiling_hz,
                                      silence_threshold=PITCH_SILENCE_THRESHOLD * global_peak / segment_peak)
            by_step = _frames_on_steps(pitch.xs(), pitch.selected_array["frequency"], dt=self._dt,
                                       sample_rate_hz=sr)
            value = by_step.get(k * self._oversample, 0.0)
            f0 = value if value > 0 else math.nan  # Praat's 0 Hz is unvoiced: NaN inside the package
        energy = ENERGY_FLOOR_DB
        samples = self._read(i_start, i_length)
        if np.any(samples):
            sound = parselmouth.Sound(samples, sampling_frequency=sr, start_time=i_start / sr)
            intensity = sound.to_intensity(minimum_pitch=self.intensity_min_pitch_hz, time_step=self._dt,
                                           subtract_mean=False)
            by_step = _frames_on_steps(intensity.xs(), intensity.values[0], dt=self._dt, sample_rate_hz=sr)
            energy = max(by_step.get(k * self._oversample, ENERGY_FLOOR_DB), ENERGY_FLOOR_DB)
        return f0, float(energy)

    def checked(self, samples: np.ndarray, *, held: int = 0) -> np.ndarray:
        """``samples`` as the flat float array :meth:`push` takes, after ``held`` samples not pushed yet.

        Parameters
        ----------
        samples : numpy.ndarray
            Mono samples at the analyser's rate.
        held : int >= 0
            Samples the caller received before these and has not pushed yet (for the number in the error).

        Returns
        -------
        numpy.ndarray
            float64, flat.

        Raises
        ------
        AudioLoadError
            A sample is not finite (its number counted from the stream's start).
        """
        samples = np.asarray(samples, dtype=float).reshape(-1)
        finite = np.isfinite(samples)
        if not finite.all():
            bad = self._received + held + int(np.argmin(finite))
            raise AudioLoadError(f"sample {bad} is not finite; audio must have no NaN or infinity")
        return samples

    def samples_needed(self) -> int:
        """Samples that must have arrived (counted from the stream's start) before the next frame can be computed:
        audio pushed before that gives no frame, however it is cut.

        Returns
        -------
        int
        """
        (p_start, p_length), (i_start, i_length) = self._segments(self._next_frame)
        return max(p_start + p_length, i_start + i_length)

    def _ready(self, k: int, *, total: int | None) -> bool:
        if total is not None:
            return k < _frame_count(total, self.sample_rate_hz, self.fps)
        (p_start, p_length), (i_start, i_length) = self._segments(k)
        return max(p_start + p_length, i_start + i_length) <= self._received

    def _run(self, *, total: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        f0, energy = [], []
        while self._ready(self._next_frame, total=total):
            value, level = self._frame(self._next_frame)
            f0.append(value)
            energy.append(level)
            self._next_frame += 1
        # keep only what later frames and the peak memory can still read
        (p_start, _), (i_start, _) = self._segments(self._next_frame)
        # folded here too, not only when a frame has sound: in digital silence no frame asks for the peak,
        # and the unfolded audio would be kept (and copied on every push) for as long as the silence lasts
        self._fold_peaks(min(p_start, i_start))
        keep_from = max(0, min(p_start, i_start, self._peak_scanned))
        if keep_from > self._buffer_start:
            self._buffer = self._buffer[keep_from - self._buffer_start:]
            self._buffer_start = keep_from
        return np.array(f0, dtype=float), np.array(energy, dtype=float)

    def push(self, samples: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Add audio; return ``(f0_hz, energy_db)`` of the frames that became complete (NaN F0 where
        unvoiced), possibly none.

        Parameters
        ----------
        samples : numpy.ndarray
            Mono samples at the analyser's rate, any number of them.

        Returns
        -------
        f0_hz, energy_db : numpy.ndarray
            One value per completed frame.

        Raises
        ------
        AudioLoadError
            A sample is not finite.
        """
        if self._finished:
            raise ParameterError("push() after finish(): start a new StreamingAnalyser for new audio")
        samples = self.checked(samples)
        self._buffer = np.concatenate([self._buffer, samples])
        self._received += samples.size
        return self._run()

    def finish(self) -> tuple[np.ndarray, np.ndarray]:
        """End of the audio: the remaining frames, analysed with silence after the end (as the whole-file
        analysis does), so the frame count is the whole file's.

        Returns
        -------
        f0_hz, energy_db : numpy.ndarray
            One value per remaining frame.
        """
        if self._finished:
            return np.zeros(0), np.zeros(0)
        self._finished = True
        return self._run(total=self._received)


def _frame_count(n_samples: int, sample_rate_hz: int, fps: float) -> int:
    from .tracks import frame_count

    return frame_count(n_samples / sample_rate_hz, fps=fps)


class RunningMedian:
    """Median of the values seen so far, from a histogram: constant memory however long the stream.

    Parameters
    ----------
    low, high : float
        Range of the histogram; values outside are counted at its ends.
    resolution : float > 0
        Bin width (the median is exact to half of it).
    half_life : float > 0 or None
        Weight of a value halves after this many further values, so the median follows a voice that
        changes over a long stream; None keeps every value at full weight.

    Examples
    --------
    >>> median = RunningMedian(0.0, 100.0, resolution=0.1)
    >>> for value in (10.0, 20.0, 30.0, 90.0):
    ...     median.add(value)
    >>> round(median.value, 1), median.count
    (25.0, 4)
    """

    def __init__(self, low: float, high: float, *, resolution: float, half_life: float | None = None) -> None:
        if not (math.isfinite(low) and math.isfinite(high) and high > low and resolution > 0):
            raise ParameterError(f"need low < high and resolution > 0, got {low!r}, {high!r}, {resolution!r}")
        self.low, self.resolution = float(low), float(resolution)
        self._counts = np.zeros(int(math.ceil((high - low) / resolution)) + 1)
        self._decay = 0.5 ** (1.0 / half_life) if half_life else 1.0
        self.count = 0
        self._median: float | None = None

    def add(self, value: float) -> None:
        """Add a value (it counts with full weight; older ones fade by the half-life).

        Parameters
        ----------
        value : float
            The new value.
        """
        if self._decay != 1.0:
            self._counts *= self._decay
            if self.count % 4096 == 0:  # weights forgotten long ago: zero, not ever smaller subnormals
                self._counts[self._counts < 1e-200] = 0.0
        index = int(np.clip(np.rint((value - self.low) / self.resolution), 0, self._counts.size - 1))
        self._counts[index] += 1.0
        self.count += 1
        self._median = None

    @property
    def value(self) -> float:
        """The median (the middle of the two middle bins when the weights split evenly); NaN
        before any value."""
        if self.count == 0:
            return math.nan
        if self._median is None:  # worked out once after each value added, however often it is read
            cumulative = np.cumsum(self._counts)
            half = cumulative[-1] / 2
            lower = int(np.searchsorted(cumulative, half - 1e-9 * cumulative[-1]))
            upper = int(np.searchsorted(cumulative, half + 1e-9 * cumulative[-1], side="right"))
            upper = min(upper, self._counts.size - 1)
            self._median = self.low + self.resolution * 0.5 * (lower + upper)
        return self._median


class CausalF0Bridge:
    """The conditioned F0 of :func:`audio_features.condition_f0`, computed from the frames up to a
    look-ahead only.

    A voiced frame keeps its F0. An unvoiced frame inside a gap whose end lies within the look-ahead is
    bridged by the shape-preserving spline of :func:`audio_features.condition_f0` through the voiced frames
    around the gap (up to :attr:`KNOTS` on each side). Where the whole gap was in sight from its start, that
    is the offline bridge exactly, once the look-ahead also reaches the voiced frame after the gap's end (the
    spline's slope there depends on it). An unvoiced frame whose gap ends beyond the look-ahead holds the
    value given to the frame before (the last voiced F0); once the end comes in sight the rest of the gap is
    bridged from that held value, so the curve never jumps. Before the first voiced frame the value is the
    first voiced F0 within the look-ahead, or 0. Values are clipped to ``[0, highest voiced F0 so far]``.

    Parameters
    ----------
    lookahead_frames : int
        Frames after each frame that its conditioned value may use.

    Examples
    --------
    With 2 frames of look-ahead, a 2-frame gap is bridged and a 4-frame gap held, then bridged once its end
    is in sight:

    >>> bridge = CausalF0Bridge(lookahead_frames=2)
    >>> raw = [100.0, np.nan, np.nan, 130.0, np.nan, np.nan, np.nan, np.nan, 100.0, 100.0]
    >>> out = [bridge.push(value) for value in raw] + bridge.finish()
    >>> [round(v) for v in out if v is not None]
    [100, 110, 120, 130, 130, 130, 126, 112, 100, 100]
    """

    KNOTS = 4

    def __init__(self, *, lookahead_frames: int) -> None:
        if isinstance(lookahead_frames, bool) or not isinstance(lookahead_frames, int) or lookahead_frames < 0:
            raise ParameterError(f"lookahead_frames must be a whole number >= 0, got {lookahead_frames!r}")
        self.lookahead_frames = lookahead_frames
        self._pending: deque[float] = deque()  # raw F0 of frames received but not given out
        self._next = 0  # index of the next frame to give out
        self._voiced_before: deque[tuple[int, float]] = deque(maxlen=self.KNOTS)
        self._last: float | None = None
        self._bridging = False  # the frame before was voiced or bridged from the voiced frames alone
        self._highest = 0.0

    def push(self, f0_hz: float) -> float | None:
        """Add the next frame's raw F0 (NaN if unvoiced); return the conditioned F0 of the frame
        ``lookahead_frames`` earlier, or None while the look-ahead fills.

        Parameters
        ----------
        f0_hz : float
            The next frame's F0, NaN where unvoiced.

        Returns
        -------
        float or None
        """
        if not math.isnan(f0_hz):
            self._highest = max(self._highest, float(f0_hz))
        self._pending.append(float(f0_hz))
        if len(self._pending) <= self.lookahead_frames:
            return None
        return self._give()

    def finish(self) -> list[float]:
        """The conditioned F0 of the frames still waiting for their look-ahead (the stream has ended).

        Returns
        -------
        list of float
        """
        return [self._give() for _ in range(len(self._pending))]

    def _give(self) -> float:
        k = self._next
        raw = self._pending.popleft()
        self._next += 1
        if not math.isnan(raw):
            value = raw
            self._voiced_before.append((k, raw))
            self._bridging = True
        else:
            ahead = [(k + 1 + i, v) for i, v in enumerate(self._pending) if not math.isnan(v)][: self.KNOTS]
            if not ahead:
                value = self._last if self._last is not None else 0.0
                self._bridging = False
            elif self._last is None:
                value = ahead[0][1]
            else:
                knots = list(self._voiced_before)
                if not self._bridging:  # the gap was held so far: go on from the value given last
                    knots = [(i, v) for i, v in knots if i < k - 1] + [(k - 1, self._last)]
                knots.extend(ahead)
                x = np.array([i for i, _ in knots], dtype=float)
                y = np.array([v for _, v in knots])
                value = float(shape_preserving_spline(x, y, np.array([float(k)]))[0])
            value = min(max(value, 0.0), self._highest)
        self._last = value
        return value


def stream_file(path: str, *, fps: float = DEFAULT_FPS, f0_floor_hz: float = DEFAULT_F0_FLOOR_HZ,
                f0_ceiling_hz: float = DEFAULT_F0_CEILING_HZ) -> tuple[np.ndarray, np.ndarray]:
    """``(f0_hz, energy_db)`` of a whole file as :class:`StreamingAnalyser` gives them live (the frames do
    not depend on how the audio arrives, so this equals any live run on the same audio).

    Parameters
    ----------
    path : str
        The audio file.
    fps : float
        Frames per second of the grid.
    f0_floor_hz, f0_ceiling_hz : float
        The pitch tracker's range.

    Returns
    -------
    f0_hz, energy_db : numpy.ndarray
    """
    from .audio import check_shape, open_sound_file
    from .features import read_all_mono

    with open_sound_file(path) as sound:
        check_shape(sound.frames, source=str(path), sample_rate_hz=sound.samplerate)
        samples = read_all_mono(sound, source=str(path), exact=True)
        analyser = StreamingAnalyser(int(sound.samplerate), fps=fps, f0_floor_hz=f0_floor_hz,
                                     f0_ceiling_hz=f0_ceiling_hz)
    first, last = analyser.push(samples), analyser.finish()
    return np.concatenate([first[0], last[0]]), np.concatenate([first[1], last[1]])
