"""Eyebrow raises from the voice.

Two rules:

- :class:`AccentRule` (the default): raise on a pitch accent, judged against the speaker's own voice. A raise
  starts where the voice, at speaking loudness, goes 4 semitones above the speaker's median F0; it lasts at
  least 300 ms and ends when the pitch falls back (1 semitone of hysteresis) or the voice stops, at most
  1.2 s later. Octave errors are filtered out (a 5-frame median over voiced frames) and only voiced frames
  count, so a spline bridge in a pause never raises the brows. It fires on any voice and any recording level.
- :class:`EyebrowRule` (the thesis's rule, kept exactly): raise on a rising crossing of the conditioned F0
  through 207 Hz, hold at least 300 ms and then while the energy stays at or above 45 dB.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from audio_features import Features

from ..errors import ConfigError
from ..fap.table import EYEBROW_FAPS


class NoRaiseWarning(UserWarning):
    """The eyebrow rule raised the brows nowhere in a recording; the message says which setting changes that."""


def no_raise_message(raises: EyebrowRaises) -> str | None:
    """One line saying why a recording got no raise and what changes it; None if it has raises."""
    if raises.events:
        return None
    if not np.isfinite(raises.f0_threshold_hz):
        return "no eyebrow raise: the recording has no voiced speech to raise them on"
    if raises.rule == "accent":
        return (f"no eyebrow raise: the voice never went above {raises.f0_threshold_hz:.0f} Hz (the accent "
                "threshold) at speaking loudness; a lower threshold raises more often "
                "(AccentRule(threshold_semitones=...), default 4)")
    return (f"no eyebrow raise: the pitch never rose through {raises.f0_threshold_hz:.0f} Hz (the thesis's rule "
            "suits voices that reach it); the accent rule follows any voice (eyebrow_rule=AccentRule()), or set "
            "a speaker-relative threshold (EyebrowRule(threshold_semitones=...))")


def warn_if_no_raise(raises: EyebrowRaises) -> None:
    """Issue a :class:`NoRaiseWarning` when the rule raised the brows nowhere."""
    message = no_raise_message(raises)
    if message is not None:
        warnings.warn(message, NoRaiseWarning, stacklevel=3)


@dataclass(frozen=True)
class EyebrowRule:
    """Parameters of the eyebrow rule; the defaults are the thesis values.

    Parameters
    ----------
    threshold_hz : float > 0, in Hz
        A rising crossing of the conditioned F0 through this value raises the brows (thesis: 207 Hz).
    threshold_semitones : float or None
        Speaker-relative alternative: the threshold becomes the median voiced F0 of the recording raised by
        this many semitones (for low or high voices). When set, ``threshold_hz`` is ignored.
    min_hold_s : float >= 0, in s
        Shortest raise (thesis: 300 ms, 9 frames at 30 fps).
    energy_threshold_db : float, in dB re 2e-5 Pa
        After the minimum hold, the raise lasts while the energy stays at or above this (thesis: 45 dB).
    energy_relative_db : float or None, in dB
        Calibration for recording level: the energy threshold becomes the recording's speech level (median
        energy of its voiced frames) plus this value (e.g. -25). When set, ``energy_threshold_db`` is ignored.
    ramp_frames : int >= 1
        Frames over which a released raise returns to neutral (thesis: 3).
    gain_ens_per_hz : float >= 0, in ENS per Hz
        While raised the displacement is ``gain_ens_per_hz * F0 + offset_ens`` (clipped at 0)...
    offset_ens : float, in ENS
        ... with this offset. The defaults give 15.7 ENS at 207 Hz and 25 ENS at 300 Hz: over speech that
        is raised a third of the time, a standard deviation near 8 ENS, inside the 5-17 ENS recorded by the
        thesis.
    """

    threshold_hz: float = 207.0
    threshold_semitones: float | None = None
    min_hold_s: float = 0.3
    energy_threshold_db: float = 45.0
    energy_relative_db: float | None = None
    ramp_frames: int = 3
    gain_ens_per_hz: float = 0.1
    offset_ens: float = -5.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.threshold_hz) and self.threshold_hz > 0):
            raise ConfigError(f"threshold_hz must be a positive number, got {self.threshold_hz!r}")
        for name in ("threshold_semitones", "energy_threshold_db", "energy_relative_db", "gain_ens_per_hz",
                     "offset_ens", "min_hold_s"):
            value = getattr(self, name)
            if value is not None and not (isinstance(value, (int, float)) and math.isfinite(value)):
                raise ConfigError(f"{name} must be a finite number, got {value!r}", parameter=name)
        if not self.min_hold_s >= 0:
            raise ConfigError(f"min_hold_s must be >= 0, got {self.min_hold_s!r}")
        if not (isinstance(self.ramp_frames, int) and self.ramp_frames >= 1):
            raise ConfigError(f"ramp_frames must be a whole number >= 1, got {self.ramp_frames!r}")
        if not self.gain_ens_per_hz >= 0:
            raise ConfigError(f"gain_ens_per_hz must be >= 0, got {self.gain_ens_per_hz!r}")

    def f0_threshold_hz(self, features: Features) -> float:
        """The F0 threshold in force for this recording."""
        if self.threshold_semitones is None:
            return self.threshold_hz
        voiced = features.f0.values[features.f0.voiced]
        if voiced.size == 0:
            return float("inf")
        return float(np.median(voiced) * 2 ** (self.threshold_semitones / 12))

    def energy_threshold(self, features: Features) -> float:
        """The energy threshold in force for this recording, in dB."""
        if self.energy_relative_db is None:
            return self.energy_threshold_db
        voiced = features.energy.values[features.f0.voiced]
        level = float(np.median(voiced)) if voiced.size else float(np.median(features.energy.values))
        return level + self.energy_relative_db


def _merge_touching(events: list[tuple[int, int]], displacement: np.ndarray) -> tuple[tuple[int, int], ...]:
    """Raises as a viewer counts them: one that starts before the brows are back at rest from the one before
    (during its ramp down) continues it, so reports, plots and the measures count the same raises."""
    merged: list[tuple[int, int]] = []
    for onset, release in events:
        if merged and np.all(displacement[merged[-1][1]:onset] > 1e-9):
            merged[-1] = (merged[-1][0], release)
        else:
            merged.append((onset, release))
    return tuple(merged)


# arrays inside: equality is identity (numpy's == is elementwise), so it stays hashable
@dataclass(frozen=True, eq=False)
class EyebrowRaises:
    """Result of the rule: the displacement (ENS) per frame and the raise events.

    ``events`` holds ``(onset_frame, release_frame)`` pairs: the raise starts at ``onset_frame`` and the
    ramp back to neutral starts at ``release_frame`` (``n_frames`` if the recording ends raised).
    """

    displacement_ens: np.ndarray
    events: tuple[tuple[int, int], ...]
    f0_threshold_hz: float
    energy_threshold_db: float
    rule: str = "thesis"

    def describe(self) -> str:
        """One line saying what the rule did, for reports."""
        if self.rule == "accent":
            return (f"accent rule: raise where the voice goes above {self.f0_threshold_hz:.0f} Hz at "
                    f">= {self.energy_threshold_db:.0f} dB; {len(self.events)} raise(s)")
        return (f"thesis rule: raise above {self.f0_threshold_hz:.0f} Hz, hold while energy >= "
                f"{self.energy_threshold_db:.0f} dB; {len(self.events)} raise(s)")

    def curves(self) -> dict[int, np.ndarray]:
        """FAP 31 = 32 (inner) and 33 = 34 (middle): both sides and both points move together."""
        return {fap: self.displacement_ens.copy() for fap in EYEBROW_FAPS}


def eyebrow_raises(features: Features, rule: EyebrowRule | None = None) -> EyebrowRaises:
    """Apply the eyebrow rule to a recording's features.

    Parameters
    ----------
    features : Features
        Conditioned F0 and energy on the frame grid.
    rule : EyebrowRule, optional
        Parameters; the thesis values by default.

    Returns
    -------
    EyebrowRaises

    Examples
    --------
    A 150 Hz tone that jumps to 250 Hz at 0.5 s (frame 15 at 30 fps) raises the brows at frame 16: frame 15's
    40 ms pitch window straddles the jump, and its F0 stays below 207 Hz:

    >>> import numpy as np
    >>> from audio_features import Audio, extract_features
    >>> t = np.arange(16000) / 16000
    >>> f0 = np.where(t < 0.5, 150.0, 250.0)
    >>> tone = 0.5 * np.sin(2 * np.pi * np.cumsum(f0) / 16000)
    >>> eyebrow_raises(extract_features(Audio(tone, 16000))).events[0][0]
    16
    """
    rule = rule or EyebrowRule()
    f0 = features.f0_conditioned.values
    energy = features.energy.values
    n = f0.shape[0]
    threshold_hz = rule.f0_threshold_hz(features)
    threshold_db = rule.energy_threshold(features)
    hold_frames = int(round(rule.min_hold_s * features.fps))  # 300 ms -> 9 frames at 30 fps
    # rising edge: F0[k-1] < threshold <= F0[k] (docs/models.md)
    crossing = np.zeros(n, bool)
    crossing[1:] = (f0[:-1] < threshold_hz) & (f0[1:] >= threshold_hz)
    magnitude = np.maximum(rule.gain_ens_per_hz * f0 + rule.offset_ens, 0.0)

    out = np.zeros(n)
    events: list[tuple[int, int]] = []
    raised = False
    onset = hold_until = 0
    ramp_from, ramp_step = 0.0, rule.ramp_frames  # ramp_step == ramp_frames: not ramping
    for k in range(n):
        if crossing[k]:
            if not raised:
                onset = k
            raised = True
            hold_until = k + hold_frames  # a new crossing while raised keeps the raise going
            ramp_step = rule.ramp_frames
        if raised and k >= hold_until and energy[k] < threshold_db:
            raised = False
            events.append((onset, k))
            ramp_from, ramp_step = out[k - 1] if k > 0 else 0.0, 0
        if raised:
            out[k] = magnitude[k]
        elif ramp_step < rule.ramp_frames:
            ramp_step += 1
            out[k] = ramp_from * (1 - ramp_step / rule.ramp_frames)
    if raised:
        events.append((onset, n))
    return EyebrowRaises(out, _merge_touching(events, out), threshold_hz, threshold_db)


#: The accent rule's raises are scaled by this from their first sizes (12 ENS at the threshold, 3 more per
#: semitone, at most 30). Beside 30 speakers of talking-head videos saying the same words
#: (``experiments/likeness.py``), at the first sizes the brows moved 0.24 as far as the people's in FAP units
#: (the person's tracked brow heights converted) and 0.14 as far through render and tracker (the face tracker
#: follows a drawn brow raise at about a third of its size). The gains that match the people's spread, fitted
#: leaving each speaker out, are 3.5 and 7.4 by the two measures; 5 lies between them (their geometric mean),
#: so both ratios fall in 0.5-1.5. A raise is then 60-150 ENS, 2.2-5.5 mm on an average face. The thesis's rule
#: (:class:`EyebrowRule`) keeps its own sizes.
BROW_SCALE = 5.0


@dataclass(frozen=True)
class AccentRule:
    """Parameters of the accent rule (the default eyebrows); see the module docstring.

    Parameters
    ----------
    threshold_semitones : float in [0, 24], in semitones
        Pitch above the speaker's median voiced F0 that raises the brows (4 semitones: a clear accent).
    hysteresis_semitones : float in [0, 12]
        The raise ends once the pitch falls this far below the threshold (after the minimum hold).
    loudness_db : float in [-60, 0], in dB
        Only frames at least this loud relative to the speaker's median voiced energy can raise.
    min_hold_s, max_hold_s : float, in s
        Shortest and longest raise (0.3 s, as the thesis; 1.2 s).
    ramp_s : float in (0, 1], in s
        Length of the rise at the start and of the return to neutral at the end (0.1 s: 3 frames at 30 fps).
    median_s : float in (0, 1], in s
        Span of the running median over voiced frames that removes short octave errors (an odd number of frames
        nearest to it: 5 at 30 fps, 5 at 25, 11 at 60), so the rule acts the same at any frame rate.
    base_ens : float >= 0, in ENS
        Raise at the threshold...
    gain_ens_per_semitone : float >= 0
        ... plus this much per semitone by which the accent's peak exceeds it ...
    max_ens : float > 0, in ENS
        ... capped here. The three were first set to 12, 3 and 30 from the thesis's recorded subjects (inner-brow
        spreads of 5 to 17 ENS); they are those times :data:`BROW_SCALE`, people's size on video.
    octave_error_semitones : float in [6, 48], in semitones
        Pitch more than this above the speaker's median is taken as a tracking error (Praat's octave jumps on
        a low voice last up to a few frames: 17-20 semitones above the median on recorded speech) and counts
        as unvoiced.
    """

    threshold_semitones: float = 4.0
    hysteresis_semitones: float = 1.0
    loudness_db: float = -10.0
    min_hold_s: float = 0.3
    max_hold_s: float = 1.2
    ramp_s: float = 0.1
    median_s: float = 1 / 6
    base_ens: float = 12.0 * BROW_SCALE
    gain_ens_per_semitone: float = 3.0 * BROW_SCALE
    max_ens: float = 30.0 * BROW_SCALE
    octave_error_semitones: float = 12.0

    def __post_init__(self) -> None:
        checks = (("threshold_semitones", 0.0, 24.0), ("hysteresis_semitones", 0.0, 12.0),
                  ("octave_error_semitones", 6.0, 48.0), ("ramp_s", 1e-3, 1.0), ("median_s", 1e-3, 1.0),
                  ("loudness_db", -60.0, 0.0), ("min_hold_s", 0.0, 10.0), ("max_hold_s", 0.0, 60.0),
                  ("base_ens", 0.0, 1000.0), ("gain_ens_per_semitone", 0.0, 1000.0), ("max_ens", 1e-9, 1000.0))
        for name, low, high in checks:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not low <= value <= high:
                # (NaN fails the range test too)
                raise ConfigError(f"{name} must be a number in [{low:g}, {high:g}], got {value!r}", parameter=name)
        if self.max_hold_s < self.min_hold_s:
            raise ConfigError(f"max_hold_s ({self.max_hold_s!r}) must be >= min_hold_s ({self.min_hold_s!r})")

    def ramp_frames_at(self, fps: float) -> int:
        """Frames of the rise and of the fall at ``fps``."""
        return max(1, int(round(self.ramp_s * fps)))

    def median_frames_at(self, fps: float) -> int:
        """Voiced frames in the octave-error median at ``fps`` (odd)."""
        frames = max(1, int(round(self.median_s * fps)))
        return frames if frames % 2 else frames + 1


def running_median(values: np.ndarray, size: int) -> np.ndarray:
    """Median of each window of ``size`` (odd) values centred on each value, edges padded with the edge value.

    Examples
    --------
    >>> running_median(np.array([1.0, 1.0, 9.0, 1.0, 2.0, 2.0]), 3).tolist()
    [1.0, 1.0, 1.0, 2.0, 2.0, 2.0]
    """
    values = np.asarray(values, float)
    if values.size == 0:
        return values.copy()
    half = size // 2
    padded = np.concatenate([np.full(half, values[0]), values, np.full(half, values[-1])])
    return np.median(np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1), axis=1)


#: Voiced frames below which a recording has no voice to judge accents against.
_MIN_VOICED_FRAMES = 15


def accent_raises(features: Features, rule: AccentRule | None = None) -> EyebrowRaises:
    """Apply the accent rule to a recording's features.

    Returns
    -------
    EyebrowRaises
        ``f0_threshold_hz`` is the speaker's threshold (median voiced F0 raised by the rule's semitones) and
        ``energy_threshold_db`` the loudness a raise needs; both are infinite for a recording without voice.

    Examples
    --------
    A 150 Hz voice that rises to 250 Hz (8.8 semitones above its median, 150 Hz) from 1.0 to 1.5 s raises the
    brows once: from frame 31 (the first whose 40 ms pitch window lies mostly past the jump at frame 30) to
    frame 45 (1.5 s), then ramps down over 3 frames:

    >>> import numpy as np
    >>> from audio_features import Audio, extract_features
    >>> t = np.arange(32000) / 16000
    >>> f0 = np.where((t >= 1.0) & (t < 1.5), 250.0, 150.0)
    >>> tone = 0.5 * np.sin(2 * np.pi * np.cumsum(f0) / 16000)
    >>> accent_raises(extract_features(Audio(tone, 16000))).events
    ((31, 45),)
    """
    rule = rule or AccentRule()
    n = features.n_frames
    out = np.zeros(n)
    voiced = features.f0.voiced
    if voiced.sum() < _MIN_VOICED_FRAMES:
        return EyebrowRaises(out, (), float("inf"), float("inf"), rule="accent")
    f0 = features.f0.values
    median_hz = float(np.median(f0[voiced]))
    # octave jumps of a few frames (a 5-frame median keeps three): counted as unvoiced
    voiced = voiced & ~(12 * np.log2(np.where(voiced, f0, median_hz) / median_hz) > rule.octave_error_semitones)
    semitones = np.full(n, -np.inf)
    voiced_index = np.flatnonzero(voiced)
    # an octave error is one or two frames: a median over 1/6 s of voiced frames removes it
    semitones[voiced_index] = running_median(12 * np.log2(f0[voiced_index] / median_hz),
                                             rule.median_frames_at(features.fps))
    energy = features.energy.values
    level_db = float(np.median(energy[voiced])) + rule.loudness_db
    accented = voiced & (energy >= level_db) & (semitones >= rule.threshold_semitones)
    onsets = accented & ~np.concatenate([[False], accented[:-1]])
    shortest = int(round(rule.min_hold_s * features.fps))
    longest = max(shortest, int(round(rule.max_hold_s * features.fps)))
    release_below = rule.threshold_semitones - rule.hysteresis_semitones
    events: list[tuple[int, int]] = []
    k = 0
    while k < n:
        if not onsets[k]:
            k += 1
            continue
        start, peak, end = k, semitones[k], k + 1
        while end < n and end - start < longest:
            if end - start >= shortest and not (voiced[end] and semitones[end] >= release_below):
                break
            peak = max(peak, semitones[end])
            end += 1
        height = min(rule.max_ens, rule.base_ens + rule.gain_ens_per_semitone * (peak - rule.threshold_semitones))
        ramp = rule.ramp_frames_at(features.fps)
        rise = np.minimum(1.0, (np.arange(end - start) + 1) / ramp)
        out[start:end] = np.maximum(out[start:end], height * rise)
        fall = height * (1 - np.arange(1, ramp + 1) / ramp)[: max(0, n - end)]
        out[end:end + fall.size] = np.maximum(out[end:end + fall.size], fall)
        events.append((start, end))
        k = end
    threshold_hz = median_hz * 2 ** (rule.threshold_semitones / 12)
    return EyebrowRaises(out, _merge_touching(events, out), threshold_hz, level_db, rule="accent")


BrowRule = EyebrowRule | AccentRule


def brow_raises(features: Features, rule: BrowRule | None = None) -> EyebrowRaises:
    """The raises of either rule; the accent rule (the default) when ``rule`` is None."""
    if isinstance(rule, EyebrowRule):
        return eyebrow_raises(features, rule)
    return accent_raises(features, rule)
