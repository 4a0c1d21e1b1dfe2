"""Tracked faces as curves: on the 30 fps grid of the sound, gaps bridged up to a limit, and written in the
``talking-heads`` formats (``<clip>.head.csv``, ``.brows.csv``, ``.mouth.csv``); and the check of how the
mouth's motion lines up with the sound.
"""

from __future__ import annotations

import contextlib
import csv
import math
import os
from dataclasses import dataclass

import numpy as np

from audio_features.atomic import atomic_path
from audio_features.tracks import frame_count

from ..dsp import centred_moving_average
from ..fap.recorded import ALL_COLUMNS, BROWS_COLUMNS, HEAD_CSV_COLUMNS, HEAD_CSV_FPS, MOUTH_COLUMNS

#: Longest stretch without the face that is bridged by interpolation, in s; longer ones stay empty.
MAX_GAP_S = 0.25


@dataclass(frozen=True, eq=False)
class TrackedCurves:
    """Per-column curves on the 30 fps grid (frame k at k / 30 s of the sound); NaN where there is no face.

    Attributes
    ----------
    columns : dict of str to array (n_frames,)
    fps : float
    bridged_frames : int
        Grid frames filled across a short gap.
    missing_frames : int
        Grid frames left empty (no face near enough in time).
    """

    columns: dict
    fps: float
    bridged_frames: int
    missing_frames: int

    @property
    def n_frames(self) -> int:
        return next(iter(self.columns.values())).size


def on_grid(times_s: np.ndarray, values: np.ndarray, *, n_frames: int, fps: float = HEAD_CSV_FPS,
            max_gap_s: float = MAX_GAP_S) -> tuple[np.ndarray, int, int]:
    """Resample observations taken at ``times_s`` (rows of ``values``, NaN rows where no face was found)
    onto the grid ``k / fps``, k < n_frames.

    A grid time gets the linear interpolation of the two observed frames around it when they are no more
    than one video frame plus ``max_gap_s`` apart; a grid time outside the observed span gets the nearest
    observation if it is within one video frame; the rest is NaN.

    Returns
    -------
    (array of shape (n_frames, n_columns), bridged frames, missing frames)
    """
    times = np.asarray(times_s, float)
    values = np.asarray(values, float)
    grid = np.arange(n_frames) / fps
    out = np.full((n_frames, values.shape[1]), np.nan)
    found = np.all(np.isfinite(values), axis=1)
    if not found.any() or n_frames == 0:
        return out, 0, n_frames
    seen_t, seen_v = times[found], values[found]
    step = float(np.median(np.diff(times))) if times.size > 1 else 1.0 / fps
    after = np.searchsorted(seen_t, grid, side="left")
    before = after - 1
    inside = (before >= 0) & (after < seen_t.size)
    exact = (after < seen_t.size) & (np.abs(seen_t[np.minimum(after, seen_t.size - 1)] - grid) < 1e-9)
    span = np.where(inside, seen_t[np.minimum(after, seen_t.size - 1)] - seen_t[np.maximum(before, 0)], np.inf)
    bridge = inside & (span <= step + max_gap_s + 1e-9)
    for column in range(values.shape[1]):
        out[bridge, column] = np.interp(grid[bridge], seen_t, seen_v[:, column])
    out[exact] = seen_v[after[exact]]
    edge = ~inside & ~exact
    nearest = np.clip(np.searchsorted(seen_t, grid), 0, seen_t.size - 1)
    nearest = np.where(np.abs(seen_t[np.maximum(nearest - 1, 0)] - grid) < np.abs(seen_t[nearest] - grid),
                       np.maximum(nearest - 1, 0), nearest)
    # the sound often outlasts the picture by a frame (encoder padding): the edge frame is held that long
    close = edge & (np.abs(seen_t[nearest] - grid) <= step + 1e-9)
    out[close] = seen_v[nearest[close]]
    # frames bridged across a real gap (more than one video frame between the observations around them)
    bridged = int(np.count_nonzero(bridge & ~exact & (span > 2.5 * step)))
    missing = int(np.count_nonzero(~np.all(np.isfinite(out), axis=1)))
    return out, bridged, missing


def tracked_curves(times_s: np.ndarray, rows: np.ndarray, *, duration_s: float, offset_s: float = 0.0,
                   max_gap_s: float = MAX_GAP_S) -> TrackedCurves:
    """The tracker's rows (columns :data:`ALL_COLUMNS`, NaN rows without a face) on the sound's grid.

    ``offset_s`` is added to every frame's time first: positive when the picture is known to run ahead of
    the sound (its motion then moves later).
    """
    n_frames = frame_count(duration_s, fps=HEAD_CSV_FPS)
    values, bridged, missing = on_grid(np.asarray(times_s, float) + offset_s, rows, n_frames=n_frames,
                                       max_gap_s=max_gap_s)
    columns = {name: values[:, index] for index, name in enumerate(ALL_COLUMNS)}
    return TrackedCurves(columns, HEAD_CSV_FPS, bridged, missing)


def _cell(value: float, digits: int) -> str:
    return "" if not math.isfinite(value) else f"{value:.{digits}f}"


def write_curves(curves: TrackedCurves, stem: str | os.PathLike[str], *,
                 pending: contextlib.ExitStack | None = None) -> list[str]:
    """Write ``<stem>.head.csv``, ``<stem>.brows.csv`` and ``<stem>.mouth.csv``, empty cells where there is no
    face; returns the paths. Each is written to a temporary file renamed when it is complete, or, given
    ``pending``, when that stack closes without an error (so that they appear together with other files)."""
    layouts = ((".head.csv", HEAD_CSV_COLUMNS[2:], 7, 6), (".brows.csv", BROWS_COLUMNS, 5, 4),
               (".mouth.csv", MOUTH_COLUMNS, 5, 4))
    written = []
    with contextlib.ExitStack() as own:
        stack = pending if pending is not None else own
        for ending, names, digits, time_digits in layouts:
            path = f"{os.fspath(stem)}{ending}"
            partial = stack.enter_context(atomic_path(path))
            with open(partial, "w", newline="") as handle:
                writer = csv.writer(handle, lineterminator="\n")
                writer.writerow(("frame", "time_s", *names))
                for frame in range(curves.n_frames):
                    writer.writerow((frame, f"{frame / curves.fps:.{time_digits}f}",
                                     *(_cell(float(curves.columns[name][frame]), digits) for name in names)))
            written.append(path)
    return written


# Audio-video sync -------------------------------------------------------------------------------------
#: Lags searched (s) and the smoothing of the mouth's motion (s).
SYNC_SEARCH_S = 0.5
SYNC_SMOOTHING_S = 0.2
#: Block length (s) and resamples of the block bootstrap that says how reliable the estimate is.
SYNC_BLOCK_S = 4.0
SYNC_RESAMPLES = 200
#: Shortest sound on which an estimate is attempted, in s; blocks fewer than this make it unreliable.
SYNC_MIN_S = 3.0
SYNC_MIN_BLOCKS = 4
#: A reliable estimate: correlation at least this, and a bootstrap half-interval at most this (ms).
RELIABLE_R = 0.2
RELIABLE_SPREAD_MS = 40.0


@dataclass(frozen=True)
class SyncEstimate:
    """How the mouth's motion lines up with the sound.

    Attributes
    ----------
    lead_ms : float or None
        How far the mouth's motion runs ahead of the sound's envelope, in ms (the lag of the highest
        correlation; negative when it trails). Speech itself leads by a few tens of ms (the lips move before
        the sound comes out), so about 30-100 ms is a clip in sync.
    r : float or None
        The correlation at that lag.
    spread_ms : float or None
        Half the 68 % interval of the lead over block-bootstrap resamples: small is reliable.
    reason : str
        Why there is no estimate, or why it is unreliable; else empty.
    """

    lead_ms: float | None
    r: float | None
    spread_ms: float | None
    reason: str = ""

    @property
    def reliable(self) -> bool:
        """A peak inside the search, correlation >= 0.2, bootstrap half-interval <= 40 ms, enough blocks."""
        return (self.lead_ms is not None and not self.reason and (self.r or 0) >= RELIABLE_R
                and self.spread_ms is not None and self.spread_ms <= RELIABLE_SPREAD_MS)

    def describe(self) -> str:
        if self.lead_ms is None:
            return f"audio-video sync not estimated ({self.reason})"
        if not self.reliable:  # a lead that cannot be trusted is not stated (a synced render read "433 ms")
            why = self.reason or f"r {self.r or 0:.2f}" + (f", +-{self.spread_ms:.0f} ms" if self.spread_ms else "")
            return f"audio-video sync could not be measured reliably ({why}): no lead is stated"
        side = "ahead of" if self.lead_ms >= 0 else "behind"
        return (f"the mouth moves {abs(self.lead_ms):.0f} ms {side} the sound (r {self.r:.2f}, "
                f"+-{self.spread_ms:.0f} ms: reliable)")


class EnvelopeAccumulator:
    """The RMS envelope of a sound on the 30 fps grid, fed block by block (memory bounded by the grid, not
    the sound): frame k covers samples from k / fps to (k + 1) / fps s."""

    def __init__(self, *, sample_rate_hz: int, fps: float = HEAD_CSV_FPS) -> None:
        self.sample_rate_hz, self.fps = sample_rate_hz, fps
        self.samples = 0
        self._sums = np.zeros(0)
        self._counts = np.zeros(0)

    def add(self, block: np.ndarray) -> None:
        block = np.asarray(block, float).reshape(-1)
        frames = ((self.samples + np.arange(block.size)) * self.fps / self.sample_rate_hz).astype(np.int64)
        size = int(frames[-1]) + 1 if block.size else 0
        if size > self._sums.size:
            self._sums = np.concatenate([self._sums, np.zeros(size - self._sums.size)])
            self._counts = np.concatenate([self._counts, np.zeros(size - self._counts.size)])
        if block.size:
            self._sums += np.bincount(frames, weights=block**2, minlength=self._sums.size)
            self._counts += np.bincount(frames, minlength=self._counts.size)
        self.samples += block.size

    def passing(self, blocks):
        """Yield ``blocks`` unchanged, adding each on the way (to fill this while writing the sound)."""
        for block in blocks:
            self.add(block)
            yield block

    def envelope(self, n_frames: int) -> np.ndarray:
        """RMS per frame, shape (n_frames,); frames past the sound are 0."""
        out = np.zeros(n_frames)
        size = min(n_frames, self._sums.size)
        out[:size] = np.sqrt(self._sums[:size] / np.maximum(self._counts[:size], 1))
        return out


def _lag_correlations(motion: np.ndarray, envelope: np.ndarray, lags: np.ndarray,
                      frames: np.ndarray | None = None) -> np.ndarray:
    """r(motion[t - lag], envelope[t]) over the frames t (all when None), for each lag."""
    n = motion.size
    frames = np.arange(n) if frames is None else frames
    out = np.full(lags.size, np.nan)
    for index, lag in enumerate(lags):
        t = frames[(frames - lag >= 0) & (frames - lag < n)]
        a, b = motion[t - lag], envelope[t]
        keep = np.isfinite(a) & np.isfinite(b)
        if keep.sum() > 10 and a[keep].std() > 0 and b[keep].std() > 0:
            out[index] = np.corrcoef(a[keep], b[keep])[0, 1]
    return out


def estimate_sync(lip_opening: np.ndarray, envelope: np.ndarray, *, fps: float = HEAD_CSV_FPS,
                  seed: int = 0) -> SyncEstimate:
    """Estimate the lead of the mouth's motion over the sound.

    The mouth's motion is the frame-to-frame change of the lip opening, averaged over 0.2 s; the sound's
    is its RMS envelope (:class:`EnvelopeAccumulator`, on the same grid). Their cross-correlation peaks
    at the lead, searched within +-0.5 s; 4 s blocks
    resampled with replacement say how much the peak moves.
    """
    opening = np.asarray(lip_opening, float)
    n = opening.size
    if n / fps < SYNC_MIN_S:
        return SyncEstimate(None, None, None, f"under {SYNC_MIN_S:g} s of video")
    if np.count_nonzero(np.isfinite(opening)) < n / 2:
        return SyncEstimate(None, None, None, "the face is missing in over half of the frames")
    change = np.abs(np.gradient(opening)) if n > 1 else np.zeros(n)  # central: centred on the frame
    known = np.isfinite(change)
    filled = np.interp(np.arange(n), np.flatnonzero(known), change[known])
    motion = centred_moving_average(filled, int(round(SYNC_SMOOTHING_S * fps)))
    motion[~known] = np.nan
    envelope = np.asarray(envelope, float)[:n]
    reach = int(round(SYNC_SEARCH_S * fps))
    lags = np.arange(-reach, reach + 1)
    curve = _lag_correlations(motion, envelope, lags)
    if not np.isfinite(curve).any():
        return SyncEstimate(None, None, None, "a still mouth or a silent sound")
    best = int(np.nanargmax(curve))
    block = max(int(round(fps)), min(int(round(SYNC_BLOCK_S * fps)), n // SYNC_MIN_BLOCKS))
    starts = np.arange(0, n, block)
    rng = np.random.default_rng(seed)
    leads = []
    for _ in range(SYNC_RESAMPLES):
        chosen = rng.choice(starts, size=starts.size, replace=True)
        frames = np.concatenate([np.arange(s, min(s + block, n)) for s in chosen])
        resampled = _lag_correlations(motion, envelope, lags, frames)
        if np.isfinite(resampled).any():
            leads.append(lags[int(np.nanargmax(resampled))])
    low, high = np.percentile(leads, [16, 84]) if leads else (np.nan, np.nan)
    reason = ""
    if starts.size < SYNC_MIN_BLOCKS:
        reason = "too short to tell"
    elif abs(lags[best]) == reach:
        reason = f"the best match is at the edge of the +-{SYNC_SEARCH_S * 1000:.0f} ms searched"
    return SyncEstimate(float(lags[best] * 1000 / fps), float(curve[best]), float((high - low) / 2 * 1000 / fps),
                        reason)
