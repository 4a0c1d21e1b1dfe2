"""Causal prosody generators: brows and head computed frame by frame from audio that is still arriving.

Each generator takes the acoustic frames one at a time (Praat F0, NaN where unvoiced, and intensity in dB,
as :class:`audio_features.streaming.StreamingAnalyser` gives them) and gives out the frame ``lookahead``
frames earlier: frame ``k`` may use the audio up to frame ``k + lookahead`` and nothing later. Where the
offline generators use a whole recording (the speaker's median pitch and level, the next voiced frame of
the F0 bridge, an accent's peak), these use what has been heard so far:

- the speaker's median voiced F0 and level are running medians over the voiced frames so far
  (:class:`SpeakerLevels`, forgetting with a half-life of five minutes of voice);
- the F0 bridge over unvoiced gaps sees the look-ahead only (:class:`audio_features.streaming.CausalF0Bridge`);
- an accent's brow raise grows with the accent's peak so far instead of taking the whole accent's peak;
- the head (:class:`LiveHeadModel`) reads prosody from 0.5 s before each frame to its look-ahead, its
  noise speed is matched frame by frame, and its pitch follows the predicted pitch only as fast as the
  predicted speed lets it (the offline generator corrects the whole head's speed over the recording instead).

``finish()`` gives out the frames still waiting for their look-ahead when the audio ends.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections import deque
from collections.abc import Sequence

import numpy as np

from audio_features.streaming import CausalF0Bridge, RunningMedian

from ...dsp import HEAD_LOWPASS_HZ
from ...errors import ConfigError
from ...fap.table import EYEBROW_FAPS, HEAD_FAPS, RADIANS_PER_AU
from ...validate import valid_seed
from ..eyebrows import AccentRule, BrowRule, EyebrowRule
from ..model_files import JsonModel, TrainingClip
from ..perlin import CHANNEL_KEYS, EYEBROW_STD_ENS, HEAD_OFFSETS_FRAMES, HEAD_STD_AU, PerlinSettings, fractal_noise
from ..regression import SPECTRUM_FRAMES, TimingFit
from .prosodic import (
    ENVELOPE_FEATURES,
    FEATURE_NAMES,
    LOUDNESS_RANGE_DB,
    MODEL_FORMAT,
    MODEL_VERSION,
    PITCH_FEATURES,
    PRESENCE_FULL_SHARE,
    read_prosodic_model,
    windowed_features,
)
from .settings import LiveHeadSettings

#: Look-ahead of the live head and brows by default, in ms (the measured trade: see docs/live.md).
DEFAULT_LOOKAHEAD_MS = 100.0

#: Weight of a voiced frame in the speaker's running medians halves after this many further voiced frames
#: (five minutes of voice at 30 fps).
LEVELS_HALF_LIFE_FRAMES = 9000
#: Voiced frames before the speaker's medians are trusted: no accent and no speech-driven head before.
MIN_VOICED_FRAMES = 15


class SpeakerLevels:
    """The speaker's median voiced F0 and median voiced level so far, in constant memory."""

    def __init__(self) -> None:
        # semitones re 1 Hz from 20 Hz to 2 kHz in 0.05 st; 0-200 dB in 0.1 dB
        self._pitch = RunningMedian(12 * math.log2(20.0), 12 * math.log2(2000.0), resolution=0.05,
                                    half_life=LEVELS_HALF_LIFE_FRAMES)
        self._level = RunningMedian(0.0, 200.0, resolution=0.1, half_life=LEVELS_HALF_LIFE_FRAMES)

    def add(self, f0_hz: float, energy_db: float) -> None:
        """Count a frame (only voiced frames count)."""
        if not math.isnan(f0_hz):
            self._pitch.add(12 * math.log2(f0_hz))
            self._level.add(energy_db)

    @property
    def voiced_frames(self) -> int:
        return self._pitch.count

    @property
    def median_f0_hz(self) -> float:
        return 2 ** (self._pitch.value / 12) if self._pitch.count else math.nan

    @property
    def level_db(self) -> float:
        return self._level.value


class _Delayed:
    """The frames received, kept for ``behind`` frames back and given out ``lookahead`` frames late."""

    def __init__(self, *, lookahead: int, behind: int) -> None:
        if isinstance(lookahead, bool) or not isinstance(lookahead, int) or lookahead < 0:
            raise ConfigError(f"lookahead must be a whole number of frames >= 0, got {lookahead!r}")
        self.lookahead = lookahead
        self.f0: deque[float] = deque(maxlen=behind + lookahead + 1)
        self.energy: deque[float] = deque(maxlen=behind + lookahead + 1)
        self.received = 0  # frames received
        self.next = 0  # next frame to give out

    def add(self, f0_hz: float, energy_db: float) -> None:
        self.f0.append(float(f0_hz))
        self.energy.append(float(energy_db))
        self.received += 1

    def at(self, frame: int) -> tuple[float, float]:
        """Frame ``frame`` (received, and not older than the memory)."""
        index = len(self.f0) - (self.received - frame)
        return self.f0[index], self.energy[index]

    def ahead(self, frame: int) -> int:
        """Frames received after ``frame``."""
        return self.received - 1 - frame


# brows ----------------------------------------------------------------------------------------------------
class LiveAccentBrows:
    """The accent rule (:class:`prosody.motion.eyebrows.AccentRule`), causally.

    The octave-error filter is the median of the semitones of the frame and of the voiced frames before and
    after it (two each at 30 fps), as offline, but only those of the later ones that the look-ahead reaches;
    the raise's height grows with the accent's peak so far.
    """

    def __init__(self, rule: AccentRule | None = None, *, fps: float, lookahead: int) -> None:
        self.rule = rule or AccentRule()
        self.fps = fps
        self._frames = _Delayed(lookahead=lookahead, behind=8)
        self._levels = SpeakerLevels()
        self._half_median = self.rule.median_frames_at(fps) // 2
        self._ramp = self.rule.ramp_frames_at(fps)
        # semitones (re 1 Hz) of the last voiced frames, for the octave-error median
        self._voiced_before: deque[float] = deque(maxlen=self._half_median)
        self._shortest = int(round(self.rule.min_hold_s * fps))
        self._longest = max(self._shortest, int(round(self.rule.max_hold_s * fps)))
        self._was_accented = False
        self._start: int | None = None  # frame where the current raise started
        self._peak = 0.0
        self._falling: list[float] = []  # the ramp down of the last raise, one value per coming frame
        self.events: list[tuple[int, int]] = []

    def push(self, f0_hz: float, energy_db: float) -> float | None:
        self._frames.add(f0_hz, energy_db)
        self._levels.add(f0_hz, energy_db)
        if self._frames.ahead(self._frames.next) < self._frames.lookahead:
            return None
        return self._give()

    def finish(self) -> list[float]:
        values = []
        while self._frames.next < self._frames.received:
            values.append(self._give())
        if self._start is not None:
            self.events.append((self._start, self._frames.received))
            self._start = None
        return values

    def _octave_error(self, f0_hz: float) -> bool:
        """A pitch too far above the speaker's median so far to be a voice's (as the offline rule judges it)."""
        median = self._levels.median_f0_hz
        return median == median and 12 * math.log2(f0_hz / median) > self.rule.octave_error_semitones

    def _semitones(self, k: int) -> float:
        """Octave-filtered semitones of voiced frame ``k`` re 1 Hz: a median over voiced neighbours."""
        f0, _ = self._frames.at(k)
        after: list[float] = []
        for j in range(k + 1, self._frames.received):
            f0_after, _ = self._frames.at(j)
            if not math.isnan(f0_after) and not self._octave_error(f0_after):
                after.append(12 * math.log2(f0_after))
                if len(after) == self._half_median:
                    break
        # five voiced frames as offline, fewer where the look-ahead does not reach the later ones
        return float(np.median([*self._voiced_before, 12 * math.log2(f0), *after]))

    def _give(self) -> float:
        rule = self.rule
        k = self._frames.next
        self._frames.next += 1
        f0, energy = self._frames.at(k)
        trusted = self._levels.voiced_frames >= MIN_VOICED_FRAMES
        voiced = not math.isnan(f0) and not (trusted and self._octave_error(f0))
        semitones = -math.inf
        if voiced:
            semitones = self._semitones(k) - 12 * math.log2(self._levels.median_f0_hz)
            self._voiced_before.append(12 * math.log2(f0))
        # the frame's own pitch must be high too: where the filter lacks later frames it lags a fall of the
        # pitch, which must not raise the brows again
        own = 12 * math.log2(f0 / self._levels.median_f0_hz) if voiced and trusted else -math.inf
        accented = (trusted and voiced and energy >= self._levels.level_db + rule.loudness_db
                    and min(semitones, own) >= rule.threshold_semitones)
        if self._start is not None:
            held = k - self._start
            release_below = rule.threshold_semitones - rule.hysteresis_semitones
            if held >= self._longest or (held >= self._shortest and not (voiced and semitones >= release_below)):
                height = self._height()
                self.events.append((self._start, k))
                self._falling = [height * (1 - i / self._ramp) for i in range(1, self._ramp + 1)]
                self._start = None
            else:
                self._peak = max(self._peak, semitones)
        if self._start is None and accented and not self._was_accented:
            self._start, self._peak = k, semitones
        self._was_accented = accented
        value = self._falling.pop(0) if self._falling else 0.0
        if self._start is not None:
            rise = min(1.0, (k - self._start + 1) / self._ramp)
            value = max(value, self._height() * rise)
        return value

    def _height(self) -> float:
        rule = self.rule
        return min(rule.max_ens, rule.base_ens + rule.gain_ens_per_semitone * (self._peak - rule.threshold_semitones))


class LiveThesisBrows:
    """The thesis's eyebrow rule (:class:`prosody.motion.eyebrows.EyebrowRule`) on the causally bridged F0;
    a speaker-relative threshold or a relative energy threshold uses the running medians."""

    def __init__(self, rule: EyebrowRule | None = None, *, fps: float, lookahead: int) -> None:
        self.rule = rule or EyebrowRule()
        self._bridge = CausalF0Bridge(lookahead_frames=lookahead)
        self._energy: deque[float] = deque()
        self._levels = SpeakerLevels()
        self._hold = int(round(self.rule.min_hold_s * fps))
        self._k = 0
        self._previous_f0 = math.nan
        self._raised = False
        self._onset = self._hold_until = 0
        self._ramp_from, self._ramp_step = 0.0, self.rule.ramp_frames
        self._last = 0.0
        self.events: list[tuple[int, int]] = []

    def push(self, f0_hz: float, energy_db: float) -> float | None:
        self._levels.add(f0_hz, energy_db)
        self._energy.append(float(energy_db))
        conditioned = self._bridge.push(f0_hz)
        return None if conditioned is None else self._give(conditioned)

    def finish(self) -> list[float]:
        values = [self._give(conditioned) for conditioned in self._bridge.finish()]
        if self._raised:
            self.events.append((self._onset, self._k))
            self._raised = False
        return values

    def _thresholds(self) -> tuple[float, float]:
        rule = self.rule
        threshold_hz = rule.threshold_hz
        if rule.threshold_semitones is not None:
            median = self._levels.median_f0_hz
            threshold_hz = median * 2 ** (rule.threshold_semitones / 12) if median == median else math.inf
        threshold_db = rule.energy_threshold_db
        if rule.energy_relative_db is not None and self._levels.voiced_frames:
            threshold_db = self._levels.level_db + rule.energy_relative_db
        return threshold_hz, threshold_db

    def _give(self, f0: float) -> float:
        rule = self.rule
        k = self._k
        self._k += 1
        energy = self._energy.popleft()
        threshold_hz, threshold_db = self._thresholds()
        # rising edge: F0[k-1] < threshold <= F0[k], and the rest as eyebrow_raises
        if k > 0 and self._previous_f0 < threshold_hz <= f0:
            if not self._raised:
                self._onset = k
            self._raised = True
            self._hold_until = k + self._hold
            self._ramp_step = rule.ramp_frames
        self._previous_f0 = f0
        if self._raised and k >= self._hold_until and energy < threshold_db:
            self._raised = False
            self.events.append((self._onset, k))
            self._ramp_from, self._ramp_step = self._last, 0
        value = 0.0
        if self._raised:
            value = max(rule.gain_ens_per_hz * f0 + rule.offset_ens, 0.0)
        elif self._ramp_step < rule.ramp_frames:
            self._ramp_step += 1
            value = self._ramp_from * (1 - self._ramp_step / rule.ramp_frames)
        self._last = value
        return value


def live_brows(rule: BrowRule | None, *, fps: float, lookahead: int) -> LiveAccentBrows | LiveThesisBrows:
    """The live form of a brow rule (the accent rule when ``rule`` is None)."""
    if isinstance(rule, EyebrowRule):
        return LiveThesisBrows(rule, fps=fps, lookahead=lookahead)
    return LiveAccentBrows(rule, fps=fps, lookahead=lookahead)


# head: prosodic features ------------------------------------------------------------------------------------
class LiveProsodicFeatures:
    """The per-frame prosodic features of :func:`prosody.motion.heads.prosodic.prosodic_features`, causally.

    Frame ``j``'s features are given out when frame ``j + 1`` arrives (the changes are central differences):
    loudness relative to the running median level, pitch relative to the running median F0, the pitch
    bridged over gaps by holding the last value (:class:`CausalF0Bridge` without look-ahead); all 0 until
    :data:`MIN_VOICED_FRAMES` voiced frames have been heard.
    """

    def __init__(self) -> None:
        self._levels = SpeakerLevels()
        self._bridge = CausalF0Bridge(lookahead_frames=0)
        self._raw: deque[tuple[float, float, float]] = deque(maxlen=3)  # (f0, energy, bridged) of the last frames
        self._received = 0

    def push(self, f0_hz: float, energy_db: float) -> np.ndarray | None:
        self._levels.add(f0_hz, energy_db)
        bridged = self._bridge.push(f0_hz)
        self._raw.append((float(f0_hz), float(energy_db), float(bridged if bridged is not None else 0.0)))
        self._received += 1
        if self._received < 2:
            return None
        return self._features(len(self._raw) - 2, last=False)

    def finish(self) -> list[np.ndarray]:
        if self._received == 0:
            return []
        return [self._features(len(self._raw) - 1, last=True)]

    def _values(self, index: int) -> tuple[float, float, float, float]:
        """(voiced, loudness, pitch, bridged pitch) of a remembered frame with the current medians."""
        f0, energy, bridged = self._raw[index]
        low, high = LOUDNESS_RANGE_DB
        loudness = (min(max(energy - self._levels.level_db, low), high) - low) / 10.0
        median = self._levels.median_f0_hz
        voiced = not math.isnan(f0)
        pitch = 12 * math.log2(f0 / median) / 4 if voiced else 0.0
        return float(voiced), loudness, pitch, 12 * math.log2(max(bridged, 1.0) / median) / 4

    def _features(self, index: int, *, last: bool) -> np.ndarray:
        if self._levels.voiced_frames < MIN_VOICED_FRAMES:
            return np.zeros(len(FEATURE_NAMES))
        voiced, loudness, pitch, bridged = self._values(index)
        before = self._values(index - 1) if index >= 1 else None
        after = None if last else self._values(index + 1)
        # np.gradient: central differences inside, one-sided at the ends
        ends = [v for v in (before, after) if v is not None]
        if len(ends) == 2:
            loudness_change = abs(after[1] - before[1]) / 2  # type: ignore[index]
            pitch_change = abs(after[3] - before[3]) / 2  # type: ignore[index]
        elif ends:
            other = ends[0]
            loudness_change, pitch_change = abs(loudness - other[1]), abs(bridged - other[3])
        else:
            loudness_change = pitch_change = 0.0
        return np.array([voiced, loudness, pitch, bridged, loudness_change, pitch_change * voiced])


def live_feature_matrix(f0_hz: np.ndarray, energy_db: np.ndarray) -> np.ndarray:
    """The per-frame features :class:`LiveProsodicFeatures` gives for a whole recording, (n_frames, 6)."""
    live = LiveProsodicFeatures()
    rows = [row for f0, energy in zip(f0_hz, energy_db, strict=True) if (row := live.push(f0, energy)) is not None]
    rows += live.finish()
    return np.array(rows).reshape(len(rows), len(FEATURE_NAMES))


def trailing_presence(voiced: np.ndarray, *, fps: float, lookahead: int, window_s: float) -> np.ndarray:
    """Speech presence 0..1 of each frame as :class:`LiveHead` judges it: the voiced share of the
    ``window_s`` ending ``lookahead`` frames after the frame (frames before the start not counted), over 0.2,
    capped at 1; 0 until :data:`MIN_VOICED_FRAMES` voiced frames have been heard."""
    voiced = np.asarray(voiced, float)
    n = voiced.size
    window = max(1, int(round(window_s * fps)))
    cumulative = np.concatenate([[0.0], np.cumsum(voiced)])
    end = np.minimum(np.arange(n) + lookahead, n - 1) + 1
    start = np.maximum(end - window, 0)
    share = (cumulative[end] - cumulative[start]) / np.maximum(end - start, 1)
    presence = np.clip(share / PRESENCE_FULL_SHARE, 0.0, 1.0)
    return np.where(cumulative[end] >= MIN_VOICED_FRAMES, presence, 0.0)


# head: the model ------------------------------------------------------------------------------------------
MODEL_KIND = "prosodic-live"  # format and version: those of the offline prosodic head's files
#: Smoothing half-width plus the change features' one frame: how far past its newest offset the
#: regression reads.
_READ_PAST_OFFSETS = 3
#: Seeds over which the model's output is calibrated.
_CALIBRATION_SEEDS = 3
#: Half-width of the window over which the noise's own speed is measured (it is known ahead), frames at 30 fps.
_OWN_SPEED_HALF_S = 0.25


class LiveHeadModel(LiveHeadSettings, JsonModel):
    """The prosodic head generator in causal form: head pitch, yaw and roll (FAP 48-50, AU) from audio up
    to ``lookahead_s`` after each frame.

    As :class:`prosody.motion.heads.prosodic.ProsodicHeadModel`: two ridge regressions read windowed prosodic
    features and predict the head's speed envelope and its pitch; coloured noise with the recorded velocity
    spectrum is rescaled frame by frame to the predicted speed and integrated with a leak back to rest, and
    the predicted pitch is mixed into the pitch axis. Here the features are those of
    :class:`LiveProsodicFeatures`, the window reaches from ``lookbehind_s`` before the frame to
    ``lookahead_s`` after it (its smoothing and the change features included), speech presence is judged over
    the ``presence_window_s`` ending at the look-ahead, and the model is trained and calibrated on features
    computed that way.

    Parameters
    ----------
    lookahead_s : float in [0, 2], in s
        Audio after each frame the model reads: the smallest look-ahead a stream needs to use it.
    lookbehind_s, step_s, ridge, pitch_share, leak_s, pitch_leak_s, idle_ratio, envelope_power
        As :class:`prosody.motion.heads.prosodic.ProsodicHeadModel` (files written before ``envelope_power``
        existed read as 1).
    pitch_follow_s : float in [0, 2], in s
        The head's pitch follows the predicted pitch with this time constant at the average predicted speed,
        longer where the predicted speed is lower (the constant divided by the relative speed): the pitch
        prediction moves the head when the speech says it moves, and holds it in between. Without it (0, as
        files written before the setting read) the prediction's own quick changes take most of the
        head's speed wherever the speech is, and the speed envelope hardly follows the prediction (0.1 s,
        the default, raised the held-out speed-envelope r at 100 ms from 0.12 to 0.26 at a pitch r of
        0.29 instead of 0.30; the figures of docs/evaluation.md).
    presence_window_s : float in [0.05, 10], in s
        Speech presence is the voiced share of this much audio up to the look-ahead (0.25 s: live, a short
        window lets the head settle soon after the voice stops, where the offline generator's centred 2 s
        window knows the pause is coming; ``prosody train --kind live --cv`` chooses it among 0.25-2 s).
    """

    kind = MODEL_KIND
    SETTINGS = LiveHeadSettings.setting_names()
    OPTIONAL_SETTINGS = {"envelope_power": 1.0, "pitch_follow_s": 0.0}

    def lookahead_frames(self, fps: float) -> int:
        """Frames of look-ahead the model reads at ``fps``."""
        return int(math.floor(self.lookahead_s * fps + 1e-9))  # floored, as the stream reads it

    def offsets_frames(self, fps: float) -> list[int]:
        """Offsets at which the smoothed features are read: from ``lookbehind_s`` back to the newest one the
        look-ahead allows."""
        newest = self.lookahead_frames(fps) - _READ_PAST_OFFSETS
        behind = int(round(self.lookbehind_s * fps))
        step = max(1, int(round(self.step_s * fps)))
        return sorted({*range(-behind, newest + 1, step), newest})

    def smoothing_frames(self, fps: float) -> int:
        return max(1, int(round(self.step_s * fps * 5 / 3)))

    # fitting ----------------------------------------------------------------------------------------------
    def fit(self, f0_hz: Sequence[np.ndarray], energy_db: Sequence[np.ndarray], motion_au: Sequence[np.ndarray],
            *, fps: float, names: Sequence[str] | None = None) -> LiveHeadModel:
        """Fit on recordings given as their acoustic frames (streamed F0 with NaN where unvoiced, and
        energy) and recorded head motion (n_frames, 3) in AU, resting pose removed."""

        self.check_settings()
        if not (len(f0_hz) == len(energy_db) == len(motion_au)) or not f0_hz:
            raise ConfigError("need the same, non-zero number of F0 tracks, energy tracks and motion recordings")
        if self.smoothing_frames(fps) // 2 + 1 > _READ_PAST_OFFSETS:
            raise ConfigError(f"step_s={self.step_s!r} smooths over more frames than the look-ahead accounts for")
        self.fps_ = float(fps)
        per_frame = [live_feature_matrix(f, e) for f, e in zip(f0_hz, energy_db, strict=True)]
        presence = [trailing_presence(~np.isnan(f), fps=fps, lookahead=self.lookahead_frames(fps),
                                      window_s=self.presence_window_s) for f in f0_hz]
        offsets, smoothing = self.offsets_frames(fps), self.smoothing_frames(fps)
        timing = TimingFit(fps)

        def designs(features: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            return (windowed_features(features[:, ENVELOPE_FEATURES], offsets, smoothing_frames=smoothing),
                    windowed_features(features[:, PITCH_FEATURES], offsets, smoothing_frames=smoothing))

        kept = [i for i, (features, motion) in enumerate(zip(per_frame, motion_au, strict=True))
                if timing.add(motion, features.shape[0], functools.partial(designs, features))]
        fitted = timing.fit(self.ridge)
        self.envelope_weights_, self.envelope_mean_, self.envelope_std_ = fitted.envelope
        self.pitch_weights_, self.pitch_mean_, self.pitch_std_ = fitted.pitch
        self.filters_, self.velocity_scale_, self.speed_rad_s_ = fitted[2:]
        spreads = timing.spreads
        self.spread_au_ = np.mean(spreads, axis=0) / RADIANS_PER_AU
        self._calibrate([self.drive(per_frame[i], presence[i]) for i in kept], spreads)
        names = list(names) if names is not None else [f"recording {i}" for i in range(len(f0_hz))]
        self.training_ = [TrainingClip(names[i], per_frame[i].shape[0], per_frame[i].shape[0] / fps) for i in kept]
        return self

    def _calibrate(self, drives: list[tuple[np.ndarray, np.ndarray]], spreads: list[np.ndarray]) -> None:
        """The noise and the pitch prediction at unit spread, then the whole at the recorded average spread per
        axis (a person's size), as the offline generator is calibrated; ``drives`` of the kept recordings."""
        self.noise_spread_ = np.ones(len(HEAD_FAPS))
        self.pitch_prediction_spread_ = 1.0
        self.output_scale_ = np.ones(len(HEAD_FAPS))
        noise = [self._synthesise(*drive, seed=seed, parts=True)[0] for drive in drives
                 for seed in range(_CALIBRATION_SEEDS)]
        spread = np.mean([n.std(axis=0) for n in noise], axis=0)
        self.noise_spread_ = np.where(spread > 0, spread, 1.0)
        pitch_spread = float(np.mean([pitch.std() for _, pitch in drives]))
        self.pitch_prediction_spread_ = pitch_spread if pitch_spread > 0 else 1.0
        ratios = np.mean([self._synthesise(*drive, seed=seed).std(axis=0) / (spreads[n] / RADIANS_PER_AU)
                          for n, drive in enumerate(drives) for seed in range(_CALIBRATION_SEEDS)], axis=0)
        self.output_scale_ = np.where(ratios > 0, 1.0 / np.where(ratios > 0, ratios, 1.0), 1.0)

    # the two predictions ----------------------------------------------------------------------------------
    def _regression(self, per_frame: np.ndarray, columns: tuple[int, ...], weights: np.ndarray, mean: np.ndarray,
                    spread: np.ndarray) -> np.ndarray:
        design = windowed_features(per_frame[:, columns], self.offsets_frames(self.fps_),
                                   smoothing_frames=self.smoothing_frames(self.fps_))
        return ((design - mean) / spread) @ weights[:-1] + weights[-1]

    def drive(self, per_frame: np.ndarray, presence: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The two predictions for a whole recording's per-frame features (what :class:`LiveHead` computes
        frame by frame): the relative speed envelope with its idle floor, and the pitch in units of its
        recorded spread, both faded by the speech presence."""
        self._check_fitted()
        envelope = self._regression(per_frame, ENVELOPE_FEATURES, self.envelope_weights_, self.envelope_mean_,
                                    self.envelope_std_)
        envelope = np.maximum(envelope, self.idle_ratio) ** self.envelope_power
        envelope = self.idle_ratio + (np.maximum(envelope, self.idle_ratio) - self.idle_ratio) * presence
        pitch = self._regression(per_frame, PITCH_FEATURES, self.pitch_weights_, self.pitch_mean_, self.pitch_std_)
        return envelope, pitch * presence

    def _synthesise(self, envelope: np.ndarray, pitch: np.ndarray, *, seed: int, parts: bool = False):
        synthesis = _Synthesis(self, seed=seed)
        rows = [synthesis.step(e, p, parts=parts) for e, p in zip(envelope, pitch, strict=True)]
        if parts:
            return np.array([r[0] for r in rows]).reshape(-1, 3), np.array([r[1] for r in rows])
        return np.array(rows).reshape(-1, 3)

    def generate_frames(self, f0_hz: np.ndarray, energy_db: np.ndarray, *, lookahead: int | None = None,
                        seed: int = 0) -> np.ndarray:
        """Head motion (n_frames, 3) in AU for a whole recording's acoustic frames, exactly as a
        :class:`LiveHead` gives it frame by frame (the vectorised form, for evaluation)."""
        self._check_fitted()
        lookahead = self.lookahead_frames(self.fps_) if lookahead is None else lookahead
        per_frame = live_feature_matrix(np.asarray(f0_hz, float), np.asarray(energy_db, float))
        presence = trailing_presence(~np.isnan(f0_hz), fps=self.fps_, lookahead=lookahead,
                                     window_s=self.presence_window_s)
        return self._synthesise(*self.drive(per_frame, presence), seed=seed)

    def start(self, *, lookahead: int | None = None, seed: int = 0) -> LiveHead:
        """A generator that takes acoustic frames one by one (see :class:`LiveHead`)."""
        return LiveHead(self, lookahead=self.lookahead_frames(self.fps_) if lookahead is None else lookahead,
                        seed=seed)

    def _check_fitted(self) -> None:
        if not hasattr(self, "filters_"):
            raise ConfigError("the model is not fitted: call fit() or load a model file")

    # persistence ------------------------------------------------------------------------------------------
    def _array_shapes(self) -> dict[str, tuple[int, ...]]:
        width = len(self.offsets_frames(getattr(self, "fps_", 30.0)))
        axes = len(HEAD_FAPS)
        envelope, pitch = len(ENVELOPE_FEATURES) * width, len(PITCH_FEATURES) * width
        return {"envelope_weights": (envelope + 1,), "envelope_mean": (envelope,), "envelope_std": (envelope,),
                "pitch_weights": (pitch + 1,), "pitch_mean": (pitch,), "pitch_std": (pitch,),
                "filters": (axes, SPECTRUM_FRAMES), "velocity_scale": (axes,), "spread_au": (axes,),
                "noise_spread": (axes,), "output_scale": (axes,)}

    def to_dict(self) -> dict:
        self._check_fitted()
        return {"format": MODEL_FORMAT, "version": MODEL_VERSION, "kind": MODEL_KIND, "fps": self.fps_,
                "settings": {name: getattr(self, name) for name in self.SETTINGS},
                "features": list(FEATURE_NAMES), "outputs": list(HEAD_FAPS),
                **{key: np.asarray(getattr(self, key + "_")).tolist() for key in self._array_shapes()},
                "speed_rad_s": self.speed_rad_s_, "pitch_prediction_spread": self.pitch_prediction_spread_,
                "training": [clip.__dict__ for clip in self.training_]}

    @classmethod
    def from_dict(cls, payload: object, *, source: str = "<dict>") -> LiveHeadModel:
        """Rebuild a model from :meth:`to_dict` output, checking every field."""
        return read_prosodic_model(
            cls, payload, source=source, kind=MODEL_KIND,
            unsupported=f"is not a live head model (this release streams with version {MODEL_VERSION} of kind "
                        f"{MODEL_KIND!r}, made by 'prosody train --kind live')",
            names={"features": list(FEATURE_NAMES), "outputs": list(HEAD_FAPS)})


class _Synthesis:
    """The motion of :class:`LiveHeadModel`, one frame at a time, from the two predictions of that frame.

    The noise does not depend on the audio, so it is drawn ahead: its own speed is measured over a centred
    0.5 s window without waiting for any audio.
    """

    BLOCK = 256

    def __init__(self, model: LiveHeadModel, *, seed: int) -> None:
        seed = valid_seed(seed)
        self.model = model
        fps = model.fps_
        self._rng = np.random.default_rng(int(seed))
        self._taps = model.filters_.shape[1]
        self._white = self._rng.standard_normal((self._taps - 1, len(HEAD_FAPS)))
        self._half = max(1, int(round(_OWN_SPEED_HALF_S * fps)))
        self._velocity: deque[np.ndarray] = deque()  # shaped noise velocity, rad/s, drawn ahead
        self._speeds: deque[float] = deque()  # its speed once scaled to the output, same frames
        self._decay = np.array([math.exp(-1.0 / ((model.pitch_leak_s if axis == 0 else model.leak_s) * fps))
                                for axis in range(len(HEAD_FAPS))])
        self._angles = np.zeros(len(HEAD_FAPS))
        self._share_noise = math.sqrt(max(0.0, 1.0 - model.pitch_share**2))
        self._scale = model.spread_au_ * model.output_scale_
        # how a noise velocity shows in the output before the final calibration (rad/s per rad/s, per axis)
        self._to_output = model.spread_au_ * RADIANS_PER_AU / model.noise_spread_
        self._to_output[0] *= self._share_noise
        self._pitch_angle = 0.0  # the predicted pitch's part of the output, rad
        self._pitch_speed = 0.0  # its speed, smoothed, rad/s
        self._followed = 0.0  # the pitch prediction as the head follows it, in units of the recorded spread
        self._follow_frames = model.pitch_follow_s * fps
        self._pitch_smoothing = math.exp(-1.0 / (_OWN_SPEED_HALF_S * fps))
        # the speed a viewer sees is the smooth one (below 4 Hz, as the measures low-pass it): the noise's own
        # speed is measured on its velocity through a windowed-sinc low-pass of 2 * reach + 1 taps
        self._reach = max(2, int(round(0.5 * fps)))
        taps = np.arange(-self._reach, self._reach + 1)
        lowpass = np.sinc(2 * HEAD_LOWPASS_HZ / fps * taps) * np.hanning(2 * self._reach + 3)[1:-1]
        self._lowpass = lowpass / lowpass.sum()
        self._context = np.zeros((0, len(HEAD_FAPS)))
        self._draw_ahead()

    def _draw(self) -> None:
        """Shape the next block of white noise into velocities (a causal FIR over the drawn noise), and
        measure their smooth speed (rows before the first frame only serve as the low-pass's context)."""
        white = np.vstack([self._white, self._rng.standard_normal((self.BLOCK, len(HEAD_FAPS)))])
        shaped = np.column_stack([np.convolve(white[:, axis], self.model.filters_[axis], mode="valid")
                                  for axis in range(len(HEAD_FAPS))]) * self.model.velocity_scale_
        self._white = white[-(self._taps - 1):]
        first = self._context.shape[0] == 0
        combined = np.vstack([self._context, shaped])
        smooth = np.column_stack([np.convolve(combined[:, axis], self._lowpass, mode="valid")
                                  for axis in range(len(HEAD_FAPS))])
        self._speeds.extend(np.sqrt(((smooth * self._to_output) ** 2).sum(axis=1)).tolist())
        self._velocity.extend(shaped[self._reach:] if first else shaped)
        self._context = combined[-2 * self._reach:]

    def _draw_ahead(self) -> None:
        while len(self._speeds) < 2 * self._half + 2 or len(self._velocity) < self._half + 2:
            self._draw()

    def step(self, envelope: float, pitch: float, *, parts: bool = False):
        """The output of one frame (AU, 3 axes) from its predicted relative speed and pitch; with ``parts``
        (calibration) the noise alone at its raw scale, and the pitch."""
        model = self.model
        self._draw_ahead()
        # the noise's own speed over the window centred on this frame (drawn ahead)
        window = 2 * self._half + 1
        own = sum(itertools.islice(self._speeds, window)) / window
        wanted = envelope * model.speed_rad_s_
        pitch_part = model.pitch_share * pitch / model.pitch_prediction_spread_
        if not parts:
            # the head follows the predicted pitch as fast as the predicted speed lets it (one step of
            # prosody.motion.heads.prosodic.follow)
            if self._follow_frames > 0:
                self._followed += (pitch_part - self._followed) * -math.expm1(-envelope / self._follow_frames)
                pitch_part = self._followed
            # the predicted pitch moves the head too: the noise makes up the rest of the wanted speed
            angle = pitch_part * model.spread_au_[0] * RADIANS_PER_AU
            instant = abs(angle - self._pitch_angle) * model.fps_
            self._pitch_angle = angle
            self._pitch_speed = self._pitch_smoothing * self._pitch_speed + (1 - self._pitch_smoothing) * instant
            floor = model.idle_ratio * model.speed_rad_s_
            wanted = math.sqrt(max(wanted**2 - self._pitch_speed**2, floor**2))
        velocity = self._velocity[self._half] * (wanted / max(own, 1e-12))
        self._velocity.popleft()
        self._speeds.popleft()
        self._angles = self._decay * self._angles + velocity / model.fps_
        noise = self._angles / model.noise_spread_
        if parts:
            return noise.copy(), pitch
        mixed = noise.copy()
        mixed[0] = pitch_part + self._share_noise * noise[0]
        return mixed * self._scale


class LiveHead:
    """Head motion (FAP 48, 49, 50 in AU) from acoustic frames arriving one by one.

    ``push(f0_hz, energy_db)`` takes the next frame and returns the motion of the frame ``lookahead``
    frames earlier (None while the look-ahead fills); ``finish()`` returns the frames still waiting.
    The result equals :meth:`LiveHeadModel.generate_frames` on the same frames.
    """

    def __init__(self, model: LiveHeadModel, *, lookahead: int, seed: int = 0) -> None:
        model._check_fitted()
        needed = model.lookahead_frames(model.fps_)
        if lookahead < needed:
            raise ConfigError(f"the head model reads {needed} frame(s) ahead ({model.lookahead_s * 1000:g} ms) but "
                              f"the stream looks {lookahead} frame(s) ahead; raise the look-ahead or use a model "
                              "trained for less")
        self.model = model
        self.lookahead = lookahead
        self._features = LiveProsodicFeatures()
        self._offsets = model.offsets_frames(model.fps_)
        self._smoothing = model.smoothing_frames(model.fps_)
        memory = -self._offsets[0] + self._smoothing + 2
        self._per_frame: deque[np.ndarray] = deque(maxlen=memory + lookahead + 4)
        self._first_row: np.ndarray | None = None  # frame 0's features: the edge held before the start
        self._rows = 0  # per-frame feature rows computed
        self._voiced: deque[float] = deque(maxlen=max(1, int(round(model.presence_window_s * model.fps_))))
        self._voiced_total = 0
        self._presence: deque[float] = deque()  # presence of frames waiting to be given out
        self._received = 0
        self._next = 0
        self._synthesis = _Synthesis(model, seed=seed)
        self._finished = False

    def push(self, f0_hz: float, energy_db: float) -> np.ndarray | None:
        self._received += 1
        voiced = 0.0 if math.isnan(f0_hz) else 1.0
        self._voiced.append(voiced)
        self._voiced_total += int(voiced)
        if self._received > self.lookahead:
            share = sum(self._voiced) / len(self._voiced)
            self._presence.append(0.0 if self._voiced_total < MIN_VOICED_FRAMES
                                  else min(1.0, share / PRESENCE_FULL_SHARE))
        row = self._features.push(f0_hz, energy_db)
        if row is not None:
            self._add_row(row)
        if self._received <= self.lookahead:
            return None
        return self._give()

    def finish(self) -> list[np.ndarray]:
        if self._finished:
            return []
        self._finished = True
        for row in self._features.finish():
            self._add_row(row)
        out = []
        while self._next < self._received:
            # the last frames' presence: the window ends at the last frame
            if len(self._presence) == 0:
                share = sum(self._voiced) / max(len(self._voiced), 1)
                self._presence.append(0.0 if self._voiced_total < MIN_VOICED_FRAMES
                                      else min(1.0, share / PRESENCE_FULL_SHARE))
            out.append(self._give())
        return out

    def _add_row(self, row: np.ndarray) -> None:
        if self._first_row is None:
            self._first_row = row
        self._per_frame.append(row)
        self._rows += 1

    def _row(self, j: int) -> np.ndarray:
        """Per-frame features of frame ``j``, edges held (before the start, and past the end once finished)."""
        if j < 0:
            assert self._first_row is not None
            return self._first_row
        j = min(j, self._rows - 1)
        return self._per_frame[len(self._per_frame) - (self._rows - j)]

    def _smoothed_at(self, k: int) -> np.ndarray:
        """The per-frame features about each offset from frame ``k``, each the mean of ``smoothing`` frames
        (one row an offset), from one block of the frames they span."""
        before = self._smoothing // 2
        first = k + min(self._offsets) - before
        block = np.array([self._row(i) for i in range(first, k + max(self._offsets) - before + self._smoothing)])
        return np.array([block[k + offset - before - first:k + offset - before - first + self._smoothing].mean(axis=0)
                         for offset in self._offsets])

    def _give(self) -> np.ndarray:
        model = self.model
        k = self._next
        self._next += 1
        presence = self._presence.popleft()
        if self._rows == 0:
            envelope, pitch = model.idle_ratio, 0.0
        else:
            smoothed = self._smoothed_at(k)
            envelope = self._linear(smoothed, ENVELOPE_FEATURES, model.envelope_weights_, model.envelope_mean_,
                                    model.envelope_std_)
            envelope = max(max(envelope, model.idle_ratio) ** model.envelope_power, model.idle_ratio)
            envelope = model.idle_ratio + (envelope - model.idle_ratio) * presence
            pitch = self._linear(smoothed, PITCH_FEATURES, model.pitch_weights_, model.pitch_mean_,
                                 model.pitch_std_) * presence
        return self._synthesis.step(envelope, pitch)

    @staticmethod
    def _linear(smoothed: np.ndarray, columns: tuple[int, ...], weights: np.ndarray, mean: np.ndarray,
                spread: np.ndarray) -> float:
        row = smoothed[:, list(columns)].reshape(-1)  # each offset's columns in turn
        return float(((row - mean) / spread) @ weights[:-1] + weights[-1])


# random ------------------------------------------------------------------------------------------------------
class LivePerlin:
    """The RANDOM condition frame by frame: the noise of :func:`prosody.motion.perlin.perlin_curves`, scaled
    by the spread of its first 10 minutes (a stream has no end to measure its own spread on), so every frame
    is known at once and the same seed gives the same frames."""

    BLOCK = 300
    #: Frames of noise whose spread sets the scale (10 minutes at 30 fps).
    REFERENCE_FRAMES = 18000

    def __init__(self, *, fps: float, seed: int = 0, settings: PerlinSettings | None = None) -> None:
        self.fps, self.seed, self.settings = fps, seed, settings
        reference = self._raw(0, self.REFERENCE_FRAMES)
        targets = {**{fap: EYEBROW_STD_ENS for fap in EYEBROW_FAPS}, **HEAD_STD_AU}
        self._mean = {fap: float(curve.mean()) if fap in HEAD_FAPS else 0.0 for fap, curve in reference.items()}
        self._gain = {fap: targets[fap] / float(curve.std()) if curve.std() > 1e-12 else 0.0
                      for fap, curve in reference.items()}
        self._block: dict[int, np.ndarray] = {}
        self._block_start = -self.BLOCK

    def _raw(self, start: int, count: int) -> dict[int, np.ndarray]:
        """The unscaled curves at frames ``start .. start + count - 1`` (brows without their negatives)."""
        brows = np.maximum(fractal_noise(count, fps=self.fps, seed=self.seed, offset_frames=start,
                                         settings=self.settings, channel=CHANNEL_KEYS["brows"]), 0.0)
        curves = {fap: brows for fap in EYEBROW_FAPS}
        for fap, offset in HEAD_OFFSETS_FRAMES.items():
            curves[fap] = fractal_noise(count, fps=self.fps, seed=self.seed, offset_frames=offset + start,
                                        settings=self.settings, channel=CHANNEL_KEYS[fap])
        return curves

    def frame(self, k: int) -> dict[int, float]:
        """FAP -> value of frame ``k`` (31-34 in ENS, 48-50 in AU)."""
        if not self._block_start <= k < self._block_start + self.BLOCK:
            self._block_start = k - k % self.BLOCK
            self._block = self._raw(self._block_start, self.BLOCK)
        i = k - self._block_start
        return {fap: float((curve[i] - self._mean[fap]) * self._gain[fap]) for fap, curve in self._block.items()}
