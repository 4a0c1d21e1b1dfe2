"""Praat pitch and intensity placed exactly on the frame grid, computed chunk by chunk.

Praat centres its analysis frames inside the sound it is given. We cut (and zero-pad) each piece of audio
so that Praat's frames fall on multiples of the analysis step ``dt = 1 / (fps * oversample)``; every
``oversample``-th analysis frame is then a grid frame, with no interpolation. Long files are analysed in
chunks with an overlap margin, so memory stays bounded and seams match a single-pass analysis:

- pitch: Praat's voicing threshold is relative to the global peak of the sound it sees, so each chunk gets
  its silence threshold rescaled by ``global_peak / chunk_peak``, which makes the decision the same as for
  the whole file; the path finder gets ``margin_s`` of context on each side of the chunk;
- intensity: purely local, no margin needed beyond the analysis window.
"""

from __future__ import annotations

import math
import multiprocessing
import os
import signal
import sys
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .defaults import MIN_F0_FLOOR_HZ
from .errors import AnalysisError, AudioLoadError, ParameterError

#: Praat's autocorrelation pitch uses 3 periods of the floor pitch as its window.
PITCH_PERIODS_PER_WINDOW = 3.0
#: Praat's intensity uses a Gaussian-like window of 6.4 periods of its minimum pitch (3.2 effective).
INTENSITY_PERIODS_PER_WINDOW = 6.4
#: Praat's default silence threshold for To Pitch (ac), relative to the global peak.
PITCH_SILENCE_THRESHOLD = 0.03
#: Intensity below this is reported as this (digital silence gives Praat's -300 dB otherwise).
ENERGY_FLOOR_DB = 0.0
#: Largest analysis step; Praat's own default for a 75 Hz floor is 10 ms.
MAX_ANALYSIS_STEP_S = 0.010

SegmentReader = Callable[[int, int], np.ndarray]
"""``read(start_sample, n_samples)`` -> mono float64 samples, zeros outside the recording."""


# arrays inside: equality is identity (numpy's == is elementwise), so it stays hashable
@dataclass(frozen=True, eq=False)
class GridAnalysis:
    """Raw analysis results on the frame grid (before F0 conditioning).

    Attributes
    ----------
    f0_hz : numpy.ndarray
        Praat's F0 per frame, NaN where unvoiced.
    energy_db : numpy.ndarray
        Praat's intensity per frame, dB re 2e-5 Pa.
    """

    f0_hz: np.ndarray
    energy_db: np.ndarray


def analysis_step(fps: float) -> tuple[float, int]:
    """Return ``(dt, oversample)``: the Praat time step and how many steps make one grid frame.

    Parameters
    ----------
    fps : float
        Frames per second of the grid.

    Returns
    -------
    dt : float
        Praat's time step, in s.
    oversample : int
        Praat steps per grid frame.

    Examples
    --------
    >>> analysis_step(30.0)
    (0.008333333333333333, 4)
    """
    oversample = max(1, math.ceil(1.0 / (fps * MAX_ANALYSIS_STEP_S) - 1e-9))
    return 1.0 / (fps * oversample), oversample


def _aligned_segment(first_j: int, n_steps: int, *, dt: float, window_s: float, sample_rate_hz: int) -> tuple[
    int, int
]:
    """Sample range ``(start, length)`` for which Praat's frames land on ``j * dt``, ``j >= first_j``.

    Praat (Sampled_shortTermAnalysis) makes ``floor((duration - window) / dt) + 1`` frames centred in the
    sound; we pick the length for ``n_steps`` frames and place the start so that their centre falls on
    the wanted grid, to within half a sample.
    """
    n_samples = math.ceil(((n_steps - 1) * dt + window_s) * sample_rate_hz) + 2
    n_frames = math.floor((n_samples / sample_rate_hz - window_s) / dt) + 1
    mid_s = first_j * dt + 0.5 * (n_frames - 1) * dt
    start = round(mid_s * sample_rate_hz - 0.5 * n_samples)
    return start, n_samples


def _frames_on_steps(xs: np.ndarray, values: np.ndarray, *, dt: float, sample_rate_hz: int) -> dict[int, float]:
    steps = np.rint(xs / dt).astype(np.int64)
    misalignment = np.abs(xs - steps * dt).max(initial=0.0)
    if misalignment > 1.01 / sample_rate_hz:  # pragma: no cover - guards the alignment arithmetic
        raise AnalysisError(f"analysis frames missed the grid by {misalignment!r} s")
    return dict(zip(steps.tolist(), values.tolist(), strict=False))


def largest_magnitude(samples: np.ndarray) -> float:
    """The largest absolute value of finite samples (0 for none), without an array of their magnitudes (a
    10-minute recording's would be 77 MB, new memory that costs more to touch than the search).

    Parameters
    ----------
    samples : numpy.ndarray
        Finite values.

    Returns
    -------
    float
    """
    return float(max(np.max(samples, initial=0.0), -np.min(samples, initial=0.0)))


@dataclass(frozen=True)
class _ChunkAnalysis:
    """Praat's F0 and intensity of a stretch of grid frames (see the module doc), as one call."""

    read: SegmentReader
    sample_rate_hz: int
    global_peak: float
    dt: float
    oversample: int
    margin_steps: int
    last_step: int
    f0_floor_hz: float
    f0_ceiling_hz: float
    intensity_min_pitch_hz: float

    def __call__(self, chunk: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
        """F0 (NaN where unvoiced) and energy (dB) of grid frames ``k0 <= k < k1``."""
        import parselmouth

        k0, k1 = chunk
        dt, oversample, rate = self.dt, self.oversample, self.sample_rate_hz
        core_steps = np.arange(k0, k1) * oversample
        f0 = np.full(k1 - k0, np.nan)
        energy = np.full(k1 - k0, ENERGY_FLOOR_DB)
        # pitch: core plus margin of path-finder context, clipped to the recording
        j0 = max(0, k0 * oversample - self.margin_steps)
        j1 = min(self.last_step, (k1 - 1) * oversample + self.margin_steps)
        start, length = _aligned_segment(j0, j1 - j0 + 1, dt=dt, window_s=PITCH_PERIODS_PER_WINDOW / self.f0_floor_hz,
                                         sample_rate_hz=rate)
        samples = self.read(start, length)
        chunk_peak = largest_magnitude(samples)
        if chunk_peak > 0:
            sound = parselmouth.Sound(samples, sampling_frequency=rate, start_time=start / rate)
            pitch = sound.to_pitch_ac(
                time_step=dt,
                pitch_floor=self.f0_floor_hz,
                pitch_ceiling=self.f0_ceiling_hz,
                silence_threshold=PITCH_SILENCE_THRESHOLD * self.global_peak / chunk_peak,
            )
            by_step = _frames_on_steps(pitch.xs(), pitch.selected_array["frequency"], dt=dt, sample_rate_hz=rate)
            # Praat's 0 Hz means unvoiced; inside the package unvoiced is NaN (STYLE.md, Types)
            values = np.array([by_step.get(j, 0.0) for j in core_steps.tolist()])
            f0 = np.where(values > 0, values, np.nan)

        window_s = INTENSITY_PERIODS_PER_WINDOW / self.intensity_min_pitch_hz
        start, length = _aligned_segment(k0 * oversample, (k1 - 1 - k0) * oversample + 1, dt=dt, window_s=window_s,
                                         sample_rate_hz=rate)
        samples = self.read(start, length)
        if np.any(samples):
            sound = parselmouth.Sound(samples, sampling_frequency=rate, start_time=start / rate)
            intensity = sound.to_intensity(minimum_pitch=self.intensity_min_pitch_hz, time_step=dt,
                                           subtract_mean=False)
            by_step = _frames_on_steps(intensity.xs(), intensity.values[0], dt=dt, sample_rate_hz=rate)
            values = np.array([by_step.get(j, ENERGY_FLOOR_DB) for j in core_steps.tolist()])
            energy = np.maximum(values, ENERGY_FLOOR_DB)
        return f0, energy


def analyse_grid(
    read: SegmentReader,
    *,
    n_samples: int,
    sample_rate_hz: int,
    global_peak: float,
    fps: float,
    f0_floor_hz: float,
    f0_ceiling_hz: float,
    intensity_min_pitch_hz: float,
    chunk_s: float,
    margin_s: float,
    source: str,
    progress: Callable[[int, int], None] | None = None,
    workers: int = 1,
) -> GridAnalysis:
    """Praat F0 (NaN where unvoiced) and intensity (dB) at every grid frame of a recording;
    ``progress(frames_done, frames_total)`` is called after each chunk.

    Parameters
    ----------
    read : SegmentReader
        Gives the mono samples of any stretch of the recording.
    n_samples, sample_rate_hz : int
        Length and rate of the recording.
    global_peak : float
        The recording's largest absolute sample (Praat's pitch thresholds are relative to it).
    fps : float
        Frames per second of the grid.
    f0_floor_hz, f0_ceiling_hz : float
        The pitch tracker's range.
    intensity_min_pitch_hz : float
        The intensity analysis's minimum pitch (its window is 3.2 periods of it).
    chunk_s, margin_s : float
        Length of the stretches analysed at a time, and the audio added on each side so that they join seamlessly.
    source : str
        How messages name the recording.
    progress : callable, optional
        Called as ``progress(frames_done, frames_total)``.
    workers : int >= 1
        Processes that analyse chunks side by side (see :func:`forked_workers`); the result is the same.

    Returns
    -------
    GridAnalysis
        F0 and intensity on the grid.
    """
    from .tracks import frame_count

    if not MIN_F0_FLOOR_HZ <= f0_floor_hz < f0_ceiling_hz:
        raise ParameterError(
            f"need {MIN_F0_FLOOR_HZ:g} <= f0_floor_hz < f0_ceiling_hz, got floor {f0_floor_hz!r} and ceiling "
            f"{f0_ceiling_hz!r} (no voice is lower than {MIN_F0_FLOOR_HZ:g} Hz)",
            parameter=("f0_floor_hz", "f0_ceiling_hz"),
        )
    if f0_ceiling_hz >= sample_rate_hz / 2:
        raise ParameterError(
            f"f0_ceiling_hz={f0_ceiling_hz!r} must be below the Nyquist frequency {sample_rate_hz / 2!r} Hz",
            parameter="f0_ceiling_hz",
        )
    n_frames = frame_count(n_samples / sample_rate_hz, fps=fps)
    dt, oversample = analysis_step(fps)
    chunk_frames = max(1, int(round(chunk_s * fps)))
    analyse = _ChunkAnalysis(read, sample_rate_hz=sample_rate_hz, global_peak=global_peak, dt=dt,
                             oversample=oversample, margin_steps=int(round(margin_s / dt)),
                             last_step=(n_frames - 1) * oversample, f0_floor_hz=f0_floor_hz,
                             f0_ceiling_hz=f0_ceiling_hz, intensity_min_pitch_hz=intensity_min_pitch_hz)
    f0 = np.full(n_frames, np.nan)
    energy = np.full(n_frames, ENERGY_FLOOR_DB)
    chunks = [(k0, min(n_frames, k0 + chunk_frames)) for k0 in range(0, n_frames, chunk_frames)]
    if progress is not None:
        progress(0, n_frames)
    for (k0, k1), (f0_part, energy_part) in _mapped(analyse, chunks, workers):
        f0[k0:k1], energy[k0:k1] = f0_part, energy_part
        if progress is not None and k1 < n_frames:
            progress(k1, n_frames)
    if not np.all(np.isfinite(energy)):  # pragma: no cover - Praat never returns NaN for finite input
        raise AudioLoadError(f"{source}: intensity analysis returned non-finite values")
    if progress is not None:
        progress(n_frames, n_frames)
    return GridAnalysis(f0_hz=f0, energy_db=energy)


#: The chunk analyses handed to forked workers, by token (a worker finds its own in the memory it was forked with).
_FORKED_TASKS: dict[int, Callable] = {}
_FORKED_LOCK = threading.Lock()
#: How long the workers may take to answer for one item (a minute's analysis takes well under a second) before
#: they are stopped and the rest is analysed in this process.
FORKED_PATIENCE_S = 120.0
#: How long stopping the workers after a failure may take (s); past it they are left to stop on their own. A
#: worker killed while it sends its answer keeps the answers' lock for ever, and the pool's own ``terminate``
#: then waits for it without end.
FORKED_STOP_S = 5.0


def forked_workers(requested: int | None = None) -> int:
    """How many processes can analyse a recording's chunks side by side here.

    Chunks are shared with the workers by forking (they inherit the samples already in memory, nothing is
    pickled), which only Linux does safely; elsewhere, and where one core is available, this is 1.

    Parameters
    ----------
    requested : int, optional
        At most this many (default: one per core this process may run on).

    Returns
    -------
    int
        >= 1.
    """
    if not sys.platform.startswith("linux") or "fork" not in multiprocessing.get_all_start_methods():
        return 1
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return max(1, min(cores, cores if requested is None else int(requested)))


def _run_forked(task: tuple[int, object]):
    token, item = task
    return _FORKED_TASKS[token](item)


def _forked_worker_starts() -> None:
    """In a forked worker: SIGTERM ends it at once, whatever handler the program set (a program's own handler,
    as the command line's that unwinds like Ctrl-C, could leave a worker holding the pool's lock), and Ctrl-C
    at the terminal is the calling process's to handle (it stops the workers)."""
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _mapped(function: Callable, items: list, workers: int):
    """``(item, function(item))`` for each item, in order: in this process, or by forked workers (where
    ``workers`` > 1 and there is more than one item; the results are the same). Workers that give no answer for
    :data:`FORKED_PATIENCE_S` (a worker killed, a lock a thread held when the process forked) are stopped and
    the items left are done here."""
    workers = min(workers, len(items))
    done = 0
    if workers > 1:
        with _FORKED_LOCK:
            token = max(_FORKED_TASKS, default=0) + 1
            _FORKED_TASKS[token] = function
        pool = multiprocessing.get_context("fork").Pool(workers, initializer=_forked_worker_starts)
        finished = False
        try:
            answers = pool.imap(_run_forked, [(token, item) for item in items])
            for item in items:
                result = answers.next(timeout=FORKED_PATIENCE_S)
                done += 1
                yield item, result
            finished = True
        except multiprocessing.TimeoutError:
            pass
        finally:
            _stop_workers(pool, finished=finished)
            with _FORKED_LOCK:
                del _FORKED_TASKS[token]
    for item in items[done:]:
        yield item, function(item)


def _stop_workers(pool, *, finished: bool) -> None:
    """End a pool of forked workers: told there is no more work when all went well (no signal), else stopped,
    waiting at most :data:`FORKED_STOP_S` for that (see there)."""
    if finished:
        pool.close()
        pool.join()
        return

    def stop() -> None:
        pool.terminate()
        pool.join()

    stopper = threading.Thread(target=stop, name="stopping forked workers", daemon=True)
    stopper.start()
    stopper.join(FORKED_STOP_S)


def array_reader(samples: np.ndarray) -> SegmentReader:
    """A :data:`SegmentReader` over an in-memory mono signal.

    Parameters
    ----------
    samples : numpy.ndarray
        The signal, mono.

    Returns
    -------
    SegmentReader
    """
    total = samples.shape[0]

    def read(start: int, length: int) -> np.ndarray:
        out = np.zeros(length)
        lo, hi = max(0, start), min(total, start + length)
        if hi > lo:
            out[lo - start : hi - start] = samples[lo:hi]
        return out

    return read


def reopenable(sound) -> bool:
    """Whether an open ``soundfile.SoundFile`` is a file on disk that another process can open by its name
    (not a stream in memory).

    Parameters
    ----------
    sound : soundfile.SoundFile
        An open file.

    Returns
    -------
    bool
    """
    return isinstance(sound.name, (str, bytes)) and os.path.isfile(sound.name)


def sound_file_reader(sound, *, source: str, total: int | None = None) -> SegmentReader:
    """A :data:`SegmentReader` that seeks in an open ``soundfile.SoundFile`` and mixes to mono.

    ``total`` is the number of samples to read (default: the header's count); a file that holds fewer, or
    whose decoder gives up, is reported as truncated or damaged. In a process forked from this one (a worker of
    :func:`analyse_grid`) it reads through the process's own opening of the file (where :func:`reopenable`),
    since processes sharing one file position would read each other's places.

    Parameters
    ----------
    sound : soundfile.SoundFile
        An open file.
    source : str
        How messages name it.
    total : int, optional
        Samples to read.

    Returns
    -------
    SegmentReader
    """
    import soundfile

    from .audio import decode_failure, truncation

    total = sound.frames if total is None else total
    owner = os.getpid()
    own: dict[int, Any] = {}  # this process's own opening of the file, where it is not the owner

    def handle():
        pid = os.getpid()
        if pid == owner:
            return sound
        if pid not in own:
            if not reopenable(sound):  # pragma: no cover - extract_features forks only for a file on disk
                raise AnalysisError(f"{source}: a stream in memory cannot be read by another process")
            own.clear()
            own[pid] = soundfile.SoundFile(sound.name)
        return own[pid]

    def read(start: int, length: int) -> np.ndarray:
        out = np.zeros(length)
        lo, hi = max(0, start), min(total, start + length)
        if hi > lo:
            target = out[lo - start : hi - start]
            try:
                sound = handle()
                sound.seek(lo)
                if sound.channels == 1:
                    got = sound.read(hi - lo, dtype="float64", out=target).shape[0]  # no intermediate copy
                else:
                    block = sound.read(hi - lo, dtype="float64", always_2d=True)
                    got = block.shape[0]
                    target[:got] = block.mean(axis=1)
            except (soundfile.SoundFileError, RuntimeError) as error:
                raise AudioLoadError(decode_failure(source, sound.format, error)) from None
            if got != hi - lo:
                raise AudioLoadError(truncation(source, sound.format, total, lo + got))
            finite = np.isfinite(target)
            if not finite.all():
                bad = lo + int(np.argmin(finite))
                raise AudioLoadError(f"{source}: sample {bad} is not finite; audio must have no NaN or infinity")
        return out

    return read
