"""Controls for speech-driven figures: the same generator driven by audio that is not the recording's.

A speech-driven head that truly follows the speech scores higher against the recorded motion with its own
audio than with audio that keeps the same statistics but not the same timing. Two such controls:

- the recording's own features circularly shifted by several offsets of at least 5 s (on a recording
  shorter than 15 s, offsets of a third of its length and more);
- another recording's features, trimmed or tiled to this recording's length.
"""

from __future__ import annotations

import numpy as np

from audio_features import F0Track, Features, Track

#: Shortest circular shift of the mismatched-audio control, in s.
MIN_SHIFT_S = 5.0
#: Number of shifts averaged.
SHIFT_COUNT = 4


def shift_offsets(n_frames: int, *, fps: float, count: int = SHIFT_COUNT) -> list[int]:
    """Circular shifts (frames) for the mismatched-audio control: ``count`` offsets spread evenly between
    5 s and the length less 5 s, so every shift moves the audio at least 5 s either way; on a recording
    shorter than 15 s, between a third and two thirds of its length. Empty below 3 frames.

    Examples
    --------
    >>> shift_offsets(900, fps=30)
    [150, 350, 550, 750]
    >>> shift_offsets(300, fps=30)
    [100, 133, 167, 200]
    """
    if n_frames < 3:
        return []
    low = int(round(MIN_SHIFT_S * fps))
    if n_frames < 3 * low:
        low = n_frames // 3
    offsets = np.linspace(low, n_frames - low, count).round().astype(int)
    return sorted({int(k) for k in offsets if 0 < k < n_frames})


def _remade(features: Features, index: np.ndarray, *, source: str) -> Features:
    """Features whose frame k is the given features' frame ``index[k]``."""
    f0 = features.f0
    return Features(
        F0Track(f0.values[index], f0.fps, f0.unit, f0.name, f0.voiced[index]),
        Track(features.f0_conditioned.values[index], features.fps, features.f0_conditioned.unit,
              features.f0_conditioned.name),
        Track(features.energy.values[index], features.fps, features.energy.unit, features.energy.name),
        index.size / features.fps,
        source,
    )


def shifted_features(features: Features, offset_frames: int) -> Features:
    """The features circularly shifted by ``offset_frames`` (frame k holds frame k - offset)."""
    n = features.n_frames
    index = (np.arange(n) - int(offset_frames)) % max(n, 1)
    return _remade(features, index, source=f"{features.source} shifted by {offset_frames} frames")


def fitted_features(other: Features, n_frames: int) -> Features:
    """Another recording's features trimmed, or tiled end to end, to ``n_frames``."""
    if other.n_frames == 0:
        raise ValueError("cannot tile an empty recording")
    index = np.arange(n_frames) % other.n_frames
    return _remade(other, index, source=f"{other.source} fitted to {n_frames} frames")
