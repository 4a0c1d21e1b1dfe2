"""F0, conditioned F0 and energy of a recording, on the FAP frame grid."""

from __future__ import annotations

import csv
import os
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .analysis import analyse_grid, array_reader, forked_workers, largest_magnitude, reopenable, sound_file_reader
from .atomic import atomic_write
from .audio import (
    ESTIMATED_LENGTH_FORMATS,
    Audio,
    check_shape,
    decode_failure,
    open_sound_file,
    read_whole,
    truncation,
)
from .defaults import DEFAULT_F0_CEILING_HZ, DEFAULT_F0_FLOOR_HZ, DEFAULT_FPS
from .errors import AudioLoadError, NoVoicedFramesWarning, ParameterError
from .inputs import open_input, reading
from .tracks import F0Track, Track

#: Column names of the features CSV, in order.
CSV_COLUMNS = ("frame", "time_s", "f0_hz", "f0_conditioned_hz", "energy_db")

#: Largest features CSV read (64 MiB: about ten hours of rows at 30 fps).
MAX_CSV_BYTES = 64 << 20
#: Highest frame rate of the grid (animation runs at 24-120 fps; the analysis step is 10 ms at most).
MAX_FPS = 1000.0
#: Slowest frame rate: one frame a second (a slower grid holds no motion; 1e-308 fps once overflowed).
MIN_FPS = 1.0
#: Samples per block when scanning a file for its peak (bounded memory).
_SCAN_BLOCK = 1 << 20
#: Files of at most this many samples (all channels) are read into memory at once (128 MiB as float64:
#: 17 minutes of 16 kHz mono); longer ones are read chunk by chunk, so memory stays bounded.
IN_MEMORY_SAMPLES = 1 << 24


# arrays inside: equality is identity (numpy's == is elementwise), so it stays hashable
@dataclass(frozen=True, eq=False)
class Features:
    """Acoustic tracks of one recording, all on the same frame grid.

    Attributes
    ----------
    f0 : F0Track
        Praat autocorrelation F0 in Hz, NaN where unvoiced.
    f0_conditioned : Track
        F0 bridged over unvoiced gaps by a cubic spline and clipped to ``[0, max voiced F0]`` (Hz).
    energy : Track
        Praat intensity in dB re 2e-5 Pa (samples taken as pascals).
    duration_s : float
        Duration of the recording.
    source : str
        Where the audio came from.
    """

    f0: F0Track
    f0_conditioned: Track
    energy: Track
    duration_s: float
    source: str

    def __post_init__(self) -> None:
        lengths = {self.f0.n_frames, self.f0_conditioned.n_frames, self.energy.n_frames}
        rates = {self.f0.fps, self.f0_conditioned.fps, self.energy.fps}
        if len(lengths) != 1 or len(rates) != 1:
            raise ParameterError(f"tracks disagree in length {sorted(lengths)!r} or rate {sorted(rates)!r}")

    @property
    def fps(self) -> float:
        return self.f0.fps

    @property
    def n_frames(self) -> int:
        return self.f0.n_frames

    def resampled(self, fps: float) -> Features:
        """The tracks on another frame grid of the same duration: energy and conditioned F0 linearly
        interpolated, the raw F0 and its voicing from the nearest frame.

        Parameters
        ----------
        fps : float
            The new grid's frames per second.

        Returns
        -------
        Features

        Examples
        --------
        >>> t = Track(np.array([40.0, 50.0, 60.0]), 30.0, "dB", "energy")
        >>> f0 = F0Track(np.array([100.0, np.nan, 120.0]), 30.0, "Hz", "f0", np.array([True, False, True]))
        >>> features = Features(f0, Track(np.array([100.0, 110.0, 120.0]), 30.0, "Hz", "f0_conditioned"), t, 0.1, "")
        >>> features.resampled(60.0).energy.values.tolist()
        [40.0, 45.0, 50.0, 55.0, 60.0, 60.0]
        """
        from .tracks import frame_count

        if not (np.isfinite(fps) and fps > 0):
            raise ParameterError(f"fps must be a positive number, got {fps!r}")
        n = frame_count(self.duration_s, fps=fps)
        old_times = np.arange(self.n_frames) / self.fps
        times = np.arange(n) / fps
        nearest = np.clip(np.rint(times * self.fps).astype(np.int64), 0, max(self.n_frames - 1, 0))
        if self.n_frames == 0:
            nearest = np.zeros(0, dtype=np.int64)

        def linear(track: Track) -> Track:
            values = np.interp(times, old_times, track.values) if self.n_frames else np.zeros(n)
            return Track(values, fps, track.unit, track.name)

        voiced = self.f0.voiced[nearest]
        f0 = F0Track(np.where(voiced, self.f0.values[nearest], np.nan), fps, self.f0.unit, self.f0.name, voiced)
        return Features(f0, linear(self.f0_conditioned), linear(self.energy), self.duration_s, self.source)

    def write_csv(self, path: str | os.PathLike[str]) -> None:
        """Write one row per frame with the columns of :data:`CSV_COLUMNS`, atomically.

        Parameters
        ----------
        path : path-like
            The CSV file; ``f0_hz`` is empty where the frame is unvoiced.
        """
        with atomic_write(path) as handle:
            writer = csv.writer(handle, lineterminator="\n")
            writer.writerow(CSV_COLUMNS)
            for k, (time_s, f0, f0c, energy) in enumerate(
                zip(self.f0.times_s, self.f0.values, self.f0_conditioned.values, self.energy.values, strict=False)
            ):
                writer.writerow(
                    [k, f"{time_s:.6f}", "" if np.isnan(f0) else f"{f0:.3f}", f"{f0c:.3f}", f"{energy:.3f}"]
                )


def read_features_csv(path: str | os.PathLike[str], *, fps: float) -> Features:
    """Read features written by :meth:`Features.write_csv` back (values as written: 3 decimals).

    Parameters
    ----------
    path : path
        CSV with the columns of :data:`CSV_COLUMNS`.
    fps : float > 0
        Frame rate the file was written at (row k is at k / fps s; checked against ``time_s``).

    Returns
    -------
    Features

    Raises
    ------
    AudioLoadError
        Missing file, other columns, rows out of order or malformed numbers.
    """
    name = str(path)
    try:
        with reading(name, AudioLoadError), open_input(path, text=True, newline="", encoding="utf-8",
                                                       max_bytes=MAX_CSV_BYTES) as handle:
            rows = list(csv.reader(handle))
    except (UnicodeDecodeError, csv.Error) as error:
        raise AudioLoadError(f"{name}: cannot be read as a features CSV ({error})") from None
    if not rows or tuple(rows[0]) != CSV_COLUMNS:
        raise AudioLoadError(f"{name}, line 1: expected the header {','.join(CSV_COLUMNS)}")
    n = len(rows) - 1
    f0, conditioned, energy = np.full(n, np.nan), np.zeros(n), np.zeros(n)
    for k, row in enumerate(rows[1:]):
        try:
            if len(row) != len(CSV_COLUMNS) or int(row[0]) != k or abs(float(row[1]) - k / fps) > 1e-5:
                raise ValueError("frame number or time out of order")
            if row[2]:
                f0[k] = float(row[2])
            conditioned[k], energy[k] = float(row[3]), float(row[4])
        except ValueError as error:
            raise AudioLoadError(f"{name}, line {k + 2}: {error}") from None
    if not (np.all(np.isfinite(conditioned)) and np.all(np.isfinite(energy))
            and np.all(np.isfinite(f0) | np.isnan(f0))):
        raise AudioLoadError(f"{name}: values must be finite")
    return Features(F0Track(f0, fps, "Hz", "f0", ~np.isnan(f0)), Track(conditioned, fps, "Hz", "f0_conditioned"),
                    Track(energy, fps, "dB", "energy"), n / fps, name)


def shape_preserving_spline(x: np.ndarray, y: np.ndarray, at: np.ndarray) -> np.ndarray:
    """The shape-preserving piecewise cubic (PCHIP, Fritsch and Carlson) through ``(x, y)``, evaluated ``at``.

    Between two knots the curve stays between their values, so a bridge over a gap never overshoots: it
    rises or falls from one end to the other, flat at a knot that is a peak or a valley. The same curve as
    ``scipy.interpolate.PchipInterpolator(x, y)`` (the tests compare them), computed here because importing
    ``scipy.interpolate`` costs about 0.4 s, a fifth of converting ten minutes of speech.

    Parameters
    ----------
    x : float array of shape (n,), n >= 2, strictly increasing
        Knots.
    y : float array of shape (n,)
        Values at the knots.
    at : float array, within [x[0], x[-1]]
        Where to evaluate.

    Returns
    -------
    float array shaped like ``at``

    Examples
    --------
    A step from 100 to 200 over a gap: flat at both ends, no swing beyond either value.

    >>> x, y = np.array([0.0, 1.0, 3.0, 4.0]), np.array([100.0, 100.0, 200.0, 200.0])
    >>> shape_preserving_spline(x, y, np.array([1.5, 2.0, 2.5]))
    array([115.625, 150.   , 184.375])
    """
    h = np.diff(x)
    slopes = np.diff(y) / h
    slope = np.empty(x.size)  # the curve's derivative at each knot
    if x.size == 2:
        slope[:] = slopes[0]
    else:
        # inside: a weighted harmonic mean of the two slopes, 0 where they differ in sign or one is 0
        w1, w2 = 2.0 * h[1:] + h[:-1], h[1:] + 2.0 * h[:-1]
        same_sign = slopes[:-1] * slopes[1:] > 0
        with np.errstate(divide="ignore", invalid="ignore"):
            harmonic = (w1 + w2) / (w1 / slopes[:-1] + w2 / slopes[1:])
        slope[1:-1] = np.where(same_sign, harmonic, 0.0)
        slope[0] = _end_slope(h[0], h[1], slopes[0], slopes[1])
        slope[-1] = _end_slope(h[-1], h[-2], slopes[-1], slopes[-2])
    segment = np.clip(np.searchsorted(x, at, side="right") - 1, 0, x.size - 2)
    width = h[segment]
    t = (at - x[segment]) / width
    # cubic Hermite basis on [0, 1]
    return ((2 * t**3 - 3 * t**2 + 1) * y[segment] + (t**3 - 2 * t**2 + t) * width * slope[segment]
            + (-2 * t**3 + 3 * t**2) * y[segment + 1] + (t**3 - t**2) * width * slope[segment + 1])


def _end_slope(h0: float, h1: float, m0: float, m1: float) -> float:
    """The derivative at an end knot: the three-point estimate, kept from changing the curve's direction
    (0 when it would point against the first slope, at most 3 times it when the next slope turns back)."""
    d = ((2.0 * h0 + h1) * m0 - h0 * m1) / (h0 + h1)
    if np.sign(d) != np.sign(m0):
        return 0.0
    if np.sign(m0) != np.sign(m1) and abs(d) > abs(3.0 * m0):
        return 3.0 * m0
    return float(d)


def condition_f0(f0: F0Track) -> Track:
    """Bridge unvoiced gaps of an F0 track with a cubic spline (the thesis's conditioning, docs/models.md).

    The spline passes through every voiced frame. It is the shape-preserving one
    (:func:`shape_preserving_spline`): a gap is bridged from the F0 before it to the F0 after it without
    overshooting either (a natural cubic spline swung to 460-480 Hz and down to 8 Hz over the pauses of real
    speech, enough to raise the brows in silence). The result is clipped to ``[0, max voiced F0]``, as
    the conditioning asks for (with this spline the clip never acts); frames before the first and after the last
    voiced frame hold the nearest voiced value. With no voiced frame at all the result is 0 everywhere and a
    :class:`NoVoicedFramesWarning` is issued.

    Parameters
    ----------
    f0 : F0Track
        Raw F0 in Hz, NaN where unvoiced.

    Returns
    -------
    Track
        Conditioned F0 in Hz, same grid.

    Examples
    --------
    >>> import numpy as np
    >>> raw = np.array([np.nan, 100.0, np.nan, 120.0, np.nan])
    >>> condition_f0(F0Track(raw, 30.0, "Hz", "f0", ~np.isnan(raw))).values.tolist()
    [100.0, 100.0, 110.0, 120.0, 120.0]
    """
    frames = np.flatnonzero(f0.voiced)
    out = np.zeros(f0.n_frames)
    if frames.size == 0:
        warnings.warn("no voiced frame found: the conditioned F0 is 0 everywhere", NoVoicedFramesWarning,
                      stacklevel=2)
    elif frames.size == 1:
        out[:] = f0.values[frames[0]]
    else:
        voiced_values = f0.values[frames]
        inside = np.arange(frames[0], frames[-1] + 1)
        out[inside] = shape_preserving_spline(frames.astype(float), voiced_values, inside.astype(float))
        out[: frames[0]] = voiced_values[0]
        out[frames[-1] + 1 :] = voiced_values[-1]
        out = np.clip(out, 0.0, voiced_values.max())
    return Track(out, f0.fps, "Hz", "f0_conditioned")


def _scan_file(sound, *, source: str) -> tuple[float, int]:
    """Global absolute peak of the mono mix and the number of samples decoded, read in blocks; rejects
    non-finite samples and reports a decoder that gives up."""
    import soundfile

    peak = 0.0
    offset = 0
    sound.seek(0)
    try:
        for block in sound.blocks(blocksize=_SCAN_BLOCK, dtype="float64", always_2d=True):
            mono = block.mean(axis=1)
            finite = np.isfinite(mono)
            if not finite.all():
                bad = offset + int(np.argmin(finite))
                raise AudioLoadError(f"{source}: sample {bad} is not finite; audio must have no NaN or infinity")
            peak = max(peak, float(np.max(np.abs(mono), initial=0.0)))
            offset += mono.shape[0]
    except (soundfile.SoundFileError, RuntimeError) as error:
        raise AudioLoadError(decode_failure(source, sound.format, error)) from None
    return peak, offset


def read_all_mono(sound, *, source: str, exact: bool) -> np.ndarray:
    """The whole of an open sound file as mono float64 samples.

    Parameters
    ----------
    sound : soundfile.SoundFile
        Open for reading (read from its start where it can seek).
    source : str
        How messages name the file.
    exact : bool
        True where the header's frame count is exact: fewer samples than it promises is truncation.

    Returns
    -------
    numpy.ndarray
        (frames,), the channels' mean.

    Raises
    ------
    AudioLoadError
        A decoding error, a truncated file, or a sample that is not finite.
    """
    import soundfile

    if sound.seekable():
        sound.seek(0)
    try:
        data = read_whole(sound)
    except (soundfile.SoundFileError, RuntimeError) as error:
        raise AudioLoadError(decode_failure(source, sound.format, error)) from None
    if exact and data.shape[0] < sound.frames:
        raise AudioLoadError(truncation(source, sound.format, sound.frames, data.shape[0]))
    mono = data.reshape(-1) if data.shape[1] == 1 else data.mean(axis=1)  # one channel: a view, no copy
    if np.isfinite(mono.sum()):  # (no array of a flag per sample; a sum that overflows is looked at below)
        return mono
    finite = np.isfinite(mono)
    if not finite.all():
        bad = int(np.argmin(finite))
        raise AudioLoadError(f"{source}: sample {bad} is not finite; audio must have no NaN or infinity")
    return mono


def extract_features(
    source: str | os.PathLike[str] | Audio,
    *,
    fps: float = DEFAULT_FPS,
    f0_floor_hz: float = DEFAULT_F0_FLOOR_HZ,
    f0_ceiling_hz: float = DEFAULT_F0_CEILING_HZ,
    intensity_min_pitch_hz: float = 100.0,
    chunk_s: float = 60.0,
    margin_s: float = 1.0,
    progress: Callable[[int, int], None] | None = None,
    workers: int = 1,
) -> Features:
    """Extract F0, conditioned F0 and energy of a recording on the frame grid.

    Files longer than :data:`IN_MEMORY_SAMPLES` are read chunk by chunk, so memory stays bounded for
    recordings of hours.

    Parameters
    ----------
    source : path or Audio
        An audio file libsndfile reads (mixed to mono), or audio already in memory.
    fps : float > 0
        Frame rate of the output grid; frame ``k`` is at ``k / fps`` seconds.
    f0_floor_hz, f0_ceiling_hz : float, 0 < floor < ceiling < Nyquist, in Hz
        Pitch search range of Praat's To Pitch (ac).
    intensity_min_pitch_hz : float > 0, in Hz
        Praat's To Intensity minimum pitch (sets the window: 6.4 periods). Praat's default, 100 Hz.
    chunk_s : float > 0, in s
        Length of audio analysed at once.
    margin_s : float >= 0, in s
        Context given to the pitch path finder on each side of a chunk.
    progress : callable, optional
        Called as ``progress(frames_done, frames_total)`` as the analysis goes (once per chunk).
    workers : int >= 1
        Processes that analyse the chunks side by side (at most :func:`~audio_features.analysis.forked_workers`
        of them; each reads its chunks from the samples in memory, or opens a long file itself). The features
        are the same to the last bit; on 2 cores, where Praat's own threads already keep 1.7 busy, a 10-minute
        file is analysed about 1.15 times as fast by 2 processes.

    Returns
    -------
    Features

    Raises
    ------
    AudioLoadError
        The file is missing, unreadable, empty, truncated or holds non-finite samples.
    ParameterError
        A parameter is out of range.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(16000) / 16000
    >>> features = extract_features(Audio(0.5 * np.sin(2 * np.pi * 200 * t), 16000))
    >>> round(float(np.nanmedian(features.f0.values)))
    200
    """
    if not (np.isfinite(fps) and MIN_FPS <= fps <= MAX_FPS):
        raise ParameterError(f"fps must be a number from {MIN_FPS:g} to {MAX_FPS:g}, got {fps!r}")
    if not chunk_s > 0 or not margin_s >= 0:
        raise ParameterError(f"need chunk_s > 0 and margin_s >= 0, got {chunk_s!r} and {margin_s!r}")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ParameterError(f"workers must be a whole number >= 1, got {workers!r}", parameter="workers")
    parallel = forked_workers(workers)
    settings: dict[str, Any] = dict(fps=fps, f0_floor_hz=f0_floor_hz, f0_ceiling_hz=f0_ceiling_hz,
                                    intensity_min_pitch_hz=intensity_min_pitch_hz, chunk_s=chunk_s,
                                    margin_s=margin_s, progress=progress)
    if isinstance(source, Audio):
        name = source.source
        grid = analyse_grid(array_reader(source.samples), n_samples=source.samples.shape[0],
                            sample_rate_hz=source.sample_rate_hz, global_peak=largest_magnitude(source.samples),
                            source=name, **settings, workers=parallel)
        duration_s = source.duration_s
    else:
        name = str(Path(source))
        with open_sound_file(source) as sound:
            check_shape(sound.frames, source=name, sample_rate_hz=sound.samplerate)
            n_samples = sound.frames
            estimated = sound.format in ESTIMATED_LENGTH_FORMATS
            # libsndfile cannot seek in some codecs (GSM 6.10): those are read in one pass, whatever their length
            if n_samples * sound.channels <= IN_MEMORY_SAMPLES or not sound.seekable():
                # one read instead of a peak scan and a second pass
                samples = read_all_mono(sound, source=name, exact=not estimated)
                n_samples = samples.shape[0]
                check_shape(n_samples, source=name, sample_rate_hz=sound.samplerate)
                reader, peak = array_reader(samples), largest_magnitude(samples)
                shareable = True
            else:
                peak, counted = _scan_file(sound, source=name)
                if estimated:
                    n_samples = counted  # the header's count was an estimate: decode what is there
                elif counted < n_samples:
                    raise AudioLoadError(truncation(name, sound.format, n_samples, counted))
                reader = sound_file_reader(sound, source=name, total=n_samples)
                # each worker opens the file itself (one open file's position cannot be shared)
                shareable = reopenable(sound)
            grid = analyse_grid(reader, n_samples=n_samples, sample_rate_hz=int(sound.samplerate),
                                global_peak=peak, source=name, **settings,
                                workers=parallel if shareable else 1)
            duration_s = n_samples / sound.samplerate
    f0 = F0Track(grid.f0_hz, fps, "Hz", "f0", ~np.isnan(grid.f0_hz))
    return Features(
        f0=f0,
        f0_conditioned=condition_f0(f0),
        energy=Track(grid.energy_db, fps, "dB", "energy"),
        duration_s=duration_s,
        source=name,
    )
