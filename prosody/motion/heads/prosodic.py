"""The default speech-driven head: motion of a person's size whose timing comes from the speech.

Two things about head motion during speech can be predicted from the audio, and one cannot:

- *how much* the head is moving at each moment (its speed envelope) follows the prosody over about half a
  second on either side: the head moves more while someone speaks, and more on loud, changing syllables;
- head *pitch* follows it too (the head rises with a louder, higher voice);
- the direction of yaw and roll does not.

So the generator predicts the speed envelope and the pitch from windowed prosodic features with two ridge
regressions, and draws the motion itself as coloured noise whose spectrum is the recorded head velocity's:
the noise's velocity is rescaled frame by frame to the predicted speed, integrated with a slow leak back to
the rest pose, and the predicted pitch is added to the pitch axis. Where there is no speech for a while the
speed falls to an idle sway. The noise is seeded: the same seed gives the same motion, bit for bit.

The motion is a displacement from the rest pose (0 on every axis): the pose a speaker holds in silence.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from typing import ClassVar

import numpy as np

from audio_features import Features

from ...dsp import HEAD_LOWPASS_HZ, SPEED_ENVELOPE_S, centred_moving_average
from ...errors import ConfigError, ModelError
from ...fap.table import HEAD_FAPS, RADIANS_PER_AU
from ...validate import valid_seed
from ..expressivity import Expressivity, shape_head
from ..model_files import JsonModel, TrainingClip, model_array, model_payload
from ..regression import SPECTRUM_FRAMES, TimingFit, finite_number
from .settings import OfflineHeadSettings

MODEL_FORMAT = "visual-prosody-head"
MODEL_VERSION = 1
MODEL_KIND = "prosodic"
#: Per-frame features, before windowing, in this order.
FEATURE_NAMES = ("voiced", "loudness", "pitch_st", "pitch_conditioned_st", "loudness_change", "pitch_change")
#: Features that drive the speed envelope and the pitch (indices into FEATURE_NAMES).
ENVELOPE_FEATURES = (0, 1, 4)
PITCH_FEATURES = (0, 1, 2, 3)
#: Loudness is the energy relative to the recording's speech level, clipped to this range (dB).
LOUDNESS_RANGE_DB = (-40.0, 10.0)
#: Voiced time below which a recording counts as holding no speech (s).
MIN_SPEECH_S = 0.5
#: Window over which speech presence is judged (s), and the voiced share that counts as full speech.
PRESENCE_WINDOW_S = 2.0
PRESENCE_FULL_SHARE = 0.2


def prosodic_features(features: Features) -> np.ndarray:
    """Per-frame prosodic features, shape (n_frames, 6), in the order of :data:`FEATURE_NAMES`.

    ``voiced`` is 1 on voiced frames; ``loudness`` is the energy above the recording's speech level (the
    median energy of its voiced frames), clipped to -40..+10 dB and shifted so that silence is 0 and speech
    level is 4 (tens of dB); ``pitch_st`` and ``pitch_conditioned_st`` are the raw (0 where unvoiced) and
    conditioned F0 above the speaker's median voiced F0, in units of 4 semitones;
    the two changes are the absolute frame-to-frame differences of loudness and of the conditioned pitch
    (the latter on voiced frames only). A recording with less than 0.5 s of voiced frames holds no speech:
    every feature is 0, as in silence.
    """
    n = features.n_frames
    voiced = features.f0.voiced
    if voiced.sum() < MIN_SPEECH_S * features.fps or n < 2:
        return np.zeros((n, len(FEATURE_NAMES)))
    energy = features.energy.values
    level_db = float(np.median(energy[voiced]))
    low, high = LOUDNESS_RANGE_DB
    loudness = (np.clip(energy - level_db, low, high) - low) / 10.0
    median_f0 = float(np.median(features.f0.values[voiced]))
    pitch = np.zeros(n)
    pitch[voiced] = 12 * np.log2(features.f0.values[voiced] / median_f0) / 4
    conditioned = features.f0_conditioned.values
    pitch_conditioned = 12 * np.log2(np.maximum(conditioned, 1.0) / median_f0) / 4
    return np.column_stack([
        voiced.astype(float), loudness, pitch, pitch_conditioned,
        np.abs(np.gradient(loudness)), np.abs(np.gradient(pitch_conditioned)) * voiced,
    ])


def windowed_features(per_frame: np.ndarray, offsets_frames: Sequence[int], *, smoothing_frames: int) -> np.ndarray:
    """Each feature smoothed over ``smoothing_frames`` and read at every offset from the frame (positive:
    later audio), edges held; shape (n_frames, n_features * len(offsets_frames))."""
    n = per_frame.shape[0]
    smooth = np.column_stack([centred_moving_average(per_frame[:, j], smoothing_frames)
                              for j in range(per_frame.shape[1])]) if n else per_frame
    index = np.arange(n)
    return np.hstack([smooth[np.clip(index + offset, 0, max(n - 1, 0))] for offset in offsets_frames])


def speech_presence(features: Features) -> np.ndarray:
    """How much speech surrounds each frame, 0..1: the voiced share of a centred 2 s window over 0.2
    (ordinary speech is voiced well over a fifth of the time), capped at 1; 0 for a recording without speech."""
    voiced = features.f0.voiced.astype(float)
    if voiced.sum() < MIN_SPEECH_S * features.fps or voiced.size == 0:
        return np.zeros(voiced.size)
    share = centred_moving_average(voiced, int(round(PRESENCE_WINDOW_S * features.fps)))
    return np.clip(share / PRESENCE_FULL_SHARE, 0.0, 1.0)


def follow(target: np.ndarray, speed: np.ndarray, *, frames: float) -> np.ndarray:
    """``target`` followed by a first-order lag whose time constant is ``frames`` divided by ``speed``, frame
    by frame: ``y[k] = y[k-1] + (target[k] - y[k-1]) * (1 - exp(-speed[k] / frames))``, from 0 (the rest
    pose).

    The head's pitch follows its predicted pitch this way (``speed`` the predicted relative speed): quick
    where the speech says the head moves, holding where it says the head is quiet. ``frames`` 0 gives the
    target itself.

    Examples
    --------
    >>> np.round(follow(np.ones(4), np.array([1.0, 1.0, 0.0, 2.0]), frames=1.0), 3)
    array([0.632, 0.865, 0.865, 0.982])
    """
    target = np.asarray(target, float)
    if frames <= 0:
        return target.copy()
    gains = -np.expm1(-np.maximum(np.asarray(speed, float), 0.0) / frames)
    out = np.empty_like(target)
    value = 0.0
    for k, (aim, gain) in enumerate(zip(target.tolist(), gains.tolist(), strict=True)):
        value += (aim - value) * gain
        out[k] = value
    return out


# The generator runs inside `prosody convert`, whose speed aim leaves no room for importing scipy.signal
# (about 0.9 s): its filters are done here with numpy's FFT.
def _fft_size(n: int) -> int:
    return 1 << max(1, int(n - 1).bit_length())


def zero_phase_lowpass(values: np.ndarray, *, fps: float, cutoff_hz: float = HEAD_LOWPASS_HZ) -> np.ndarray:
    """Low-pass along the first axis with the gain of a 4th-order Butterworth filter run forwards and
    backwards, ``1 / (1 + (f / cutoff)^8)``, applied in the frequency domain.

    As ``scipy.signal.sosfiltfilt`` does, the ends are extended by odd reflection (value and slope continue);
    the straight line between the extension's ends is taken out before the transform and put back after, so
    the transform sees no jump where it wraps around.
    """
    values = np.asarray(values, float)
    n = values.shape[0]
    if n < 2 or cutoff_hz >= fps / 2:
        return values.copy()
    pad = min(n - 1, int(round(2 * fps / cutoff_hz)))
    first, last = values[:1], values[-1:]
    padded = np.concatenate([2 * first - values[pad:0:-1], values, 2 * last - values[-2:-pad - 2:-1]], axis=0)
    shape = (-1,) + (1,) * (values.ndim - 1)
    ramp = np.linspace(0.0, 1.0, padded.shape[0]).reshape(shape)
    line = padded[:1] + (padded[-1:] - padded[:1]) * ramp
    size = _fft_size(padded.shape[0])
    frequencies = np.fft.rfftfreq(size, d=1.0 / fps)
    gain = 1.0 / (1.0 + (frequencies / cutoff_hz) ** 8)
    spectrum = np.fft.rfft(padded - line, n=size, axis=0)
    filtered = np.fft.irfft(spectrum * gain.reshape(shape), n=size, axis=0)[: padded.shape[0]] + line
    return filtered[pad:pad + n]


def smooth_speed_envelope(angles_rad: np.ndarray, *, fps: float) -> np.ndarray:
    """The speed envelope of :func:`prosody.dsp.speed_envelope` (4 Hz low-pass, central differences,
    norm over the axes, centred 0.5 s average), with the low-pass of :func:`zero_phase_lowpass`."""
    smooth = zero_phase_lowpass(angles_rad, fps=fps)
    if smooth.shape[0] < 2:
        return np.zeros(smooth.shape[0])
    speed = np.sqrt(((np.gradient(smooth, axis=0) * fps) ** 2).sum(axis=1))
    return centred_moving_average(speed, int(round(SPEED_ENVELOPE_S * fps)))


def _causal_convolve(values: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """``sum_k kernel[k] * values[t - k]`` for each column, by FFT; same length as ``values``."""
    n = values.shape[0]
    size = _fft_size(n + kernel.size)
    spectrum = np.fft.rfft(values, n=size, axis=0) * np.fft.rfft(kernel, n=size)[:, None]
    return np.fft.irfft(spectrum, n=size, axis=0)[:n]


def read_prosodic_model(cls, payload: object, *, source: str, kind: str, unsupported: str, names: dict[str, list],
                        check_settings: Callable[[dict, Callable[[str], ModelError]], None] | None = None):
    """A model of class ``cls`` (offline or live prosodic head) from its file's data, checking every field:
    the format, the ``version`` and ``kind`` (``unsupported`` ends the message when they differ), the settings
    (``check_settings(settings, fail)`` first, then the model's own checks), the frame rate, the ``names``
    fields (features and outputs) and the fitted arrays. Errors are :class:`ModelError` naming ``source``."""

    def fail(problem: str) -> ModelError:
        return ModelError(f"{source}: {problem}")

    payload = model_payload(payload, format_name=MODEL_FORMAT, source=source)
    if payload.get("version") != MODEL_VERSION or payload.get("kind") != kind:
        if payload.get("kind") == "prosodic-live" and kind != "prosodic-live":
            raise fail("a live head model (kind 'prosodic-live') is for 'prosody stream'; convert, compare and "
                       "preview take a model from 'prosody train' without --kind live")
        if payload.get("kind") == "prosodic" and kind == "prosodic-live":
            raise fail("an offline head model (kind 'prosodic') is for convert, compare and preview; 'prosody "
                       "stream' takes a model from 'prosody train --kind live'")
        raise fail(f"model version {payload.get('version')!r} of kind {payload.get('kind')!r} {unsupported}")
    try:
        settings = payload["settings"]
        if isinstance(settings, dict):
            settings = {**getattr(cls, "OPTIONAL_SETTINGS", {}), **settings}
        if not isinstance(settings, dict) or set(settings) != set(cls.SETTINGS):
            raise fail(f"\"settings\" must hold exactly {', '.join(cls.SETTINGS)}")
        if check_settings is not None:
            check_settings(settings, fail)
        model = cls(**settings)
        try:
            model.check_settings()
        except ConfigError as error:
            raise fail(str(error)) from None
        fps = payload["fps"]
        if not finite_number(fps) or not 0 < fps <= 1000:
            raise fail(f"fps {fps!r} must be a number in (0, 1000]")
        model.fps_ = float(fps)
        if any(list(payload[key]) != value for key, value in names.items()):
            raise fail("features and outputs differ from the ones this release computes")
        _read_fitted_fields(model, payload, fail)
    except ModelError:
        raise
    except (KeyError, TypeError, ValueError, OverflowError) as error:
        raise fail(f"missing or malformed field ({error!r})") from None
    return model


def _read_fitted_fields(model, payload: dict, fail: Callable[[str], ModelError]) -> None:
    """Set the learnt attributes a prosodic head model file holds (the arrays of ``model._array_shapes()``,
    the two spreads and the training record), checking each."""
    for key, shape in model._array_shapes().items():
        setattr(model, key + "_", model_array(payload, key, shape, fail))
    for key in ("envelope_std", "pitch_std", "velocity_scale", "spread_au", "noise_spread", "output_scale"):
        if np.any(getattr(model, key + "_") <= 0):
            raise fail(f"field {key!r} must hold positive numbers")
    for key in ("speed_rad_s", "pitch_prediction_spread"):
        value = payload[key]
        if not finite_number(value) or not value > 0:
            raise fail(f"field {key!r} must be a positive number, got {value!r}")
        setattr(model, key + "_", float(value))
    model.training_ = [TrainingClip.from_dict(c) for c in payload["training"]]


class ProsodicHeadModel(OfflineHeadSettings, JsonModel):
    """Head pitch, yaw and roll (FAP 48-50, AU) from speech: a predicted speed envelope driving coloured
    noise, plus a predicted head pitch.

    Parameters
    ----------
    lookbehind_s, lookahead_s : float in [0, 5], in s
        Prosody is read from ``lookbehind_s`` before to ``lookahead_s`` after each frame (0.5 s each: the
        head leads the voice by 0.1-0.4 s).
    step_s : float > 0, in s
        Spacing of the points read inside the window (0.1 s).
    ridge : float >= 0
        Ridge penalty of both regressions, per standardised column.
    pitch_share : float in [0, 1]
        Share of the pitch axis's spread that comes from the predicted pitch; the rest is noise.
    leak_s : float > 0, in s
        Time constant of the pull back to the rest pose (yaw and roll).
    pitch_leak_s : float > 0, in s
        The same for the pitch axis's noise, shorter: its slow part is the prediction.
    idle_ratio : float in [0, 1]
        Speed of a head at rest, as a share of its average speed while speaking.
    speed_iterations : int in [0, 10]
        Passes that correct the noise so that the whole head's speed follows the prediction (3, the default,
        as the shipped model's cross-validation chose).
    envelope_power : float in [1, 4]
        The predicted speed envelope is raised to this power (1: as predicted; 2, the default and the
        shipped model's, was chosen by cross-validation among 1, 2 and 3): above 1 the head moves faster on
        strong moments and slower on weak ones, at the same overall size (bursts and holds). Files written
        before this setting existed read as 1.
    burst_power : float in [0, 1]
        The generated motion goes through the expressivity controls' power reshaping at this value
        (:class:`prosody.motion.expressivity.HeadShaper`): the velocity times the moment's relative speed to
        the power ``2 * burst_power``, at the same average speed, so the head moves in bursts and holds still
        between them as people do. 0.5, the default, brings the angular speed's 10th, 50th and 90th percentiles
        within 1.5 times the recording's on the 49 clips at hand held out by speaker (1.13 / 1.11 / 1.02; on
        the seven talking-heads clips 1.64 / 1.57 / 1.03: the figures of docs/evaluation.md); 0 leaves the motion as the
        generator makes it. Files written before this setting existed read as 0.
    pitch_follow_s : float in [0, 2], in s
        The head's pitch follows the predicted pitch with this time constant at the average predicted speed,
        longer where the predicted speed is lower (:func:`follow`): the prediction moves the head where the
        speech says it moves and holds it where it says it is quiet. 0 takes the prediction as it is (files
        written before this setting existed read as 0); cross-validation chooses between 0 and 0.2.

    Attributes
    ----------
    envelope_weights_, envelope_mean_, envelope_std_ : arrays
        Speed-envelope regression (envelope relative to the recording's average speed).
    pitch_weights_, pitch_mean_, pitch_std_ : arrays
        Pitch regression (pitch in units of its recorded spread).
    filters_ : array (3, 128)
        Noise-shaping taps per axis.
    velocity_scale_ : array (3,)
        RMS recorded velocity per axis, rad/s.
    speed_rad_s_ : float
        Average recorded head speed, rad/s.
    spread_au_ : array (3,)
        Average recorded spread per axis, AU.
    noise_spread_, pitch_prediction_spread_, output_scale_
        Calibration: the noise's and the prediction's own spreads, and the final per-axis factors that make
        the average generated / recorded spread 1.
    fps_ : float
    training_ : list of TrainingClip
    """

    kind = MODEL_KIND

    def offsets_frames(self, fps: float) -> list[int]:
        """Frame offsets read around each frame."""
        behind = int(round(self.lookbehind_s * fps))
        ahead = int(round(self.lookahead_s * fps))
        step = max(1, int(round(self.step_s * fps)))
        return sorted({*range(-behind, ahead + 1, step), ahead})

    def _smoothing(self, fps: float) -> int:
        return max(1, int(round(self.step_s * fps * 5 / 3)))  # 5 frames at 30 fps with a 0.1 s step

    def _design(self, features: Features) -> tuple[np.ndarray, np.ndarray]:
        per_frame = prosodic_features(features)
        offsets = self.offsets_frames(features.fps)
        smoothing = self._smoothing(features.fps)
        return (windowed_features(per_frame[:, ENVELOPE_FEATURES], offsets, smoothing_frames=smoothing),
                windowed_features(per_frame[:, PITCH_FEATURES], offsets, smoothing_frames=smoothing))

    # fitting --------------------------------------------------------------------------------------------
    def fit(self, features: Sequence[Features], motion_au: Sequence[np.ndarray],
            names: Sequence[str] | None = None) -> ProsodicHeadModel:
        """Fit on recordings: their features and recorded head motion, shape (n_frames, 3) in AU (the
        resting pose, e.g. each recording's median, already removed)."""
        self.check_settings()
        if len(features) != len(motion_au) or not features:
            raise ConfigError("need the same, non-zero number of feature sets and motion recordings")
        rates = {f.fps for f in features}
        if len(rates) != 1:
            raise ConfigError(f"training recordings have different frame rates {sorted(rates)!r}")
        fps = rates.pop()
        timing = TimingFit(fps)
        for feature_set, motion in zip(features, motion_au, strict=True):
            timing.add(motion, feature_set.n_frames, functools.partial(self._design, feature_set))
        fitted = timing.fit(self.ridge)
        self.envelope_weights_, self.envelope_mean_, self.envelope_std_ = fitted.envelope
        self.pitch_weights_, self.pitch_mean_, self.pitch_std_ = fitted.pitch
        self.filters_, self.velocity_scale_, self.speed_rad_s_ = fitted[2:]
        spreads = timing.spreads
        self.fps_ = float(fps)
        # calibration over the training recordings and a few seeds: each part at unit spread, then the
        # whole at the recorded average spread per axis (a person's size)
        self.spread_au_ = np.mean(spreads, axis=0) / RADIANS_PER_AU
        self.noise_spread_ = np.ones(len(HEAD_FAPS))
        self.pitch_prediction_spread_ = 1.0
        self.output_scale_ = np.ones(len(HEAD_FAPS))
        seeds = range(3)
        self.noise_spread_ = np.mean([self._noise_angles(f, seed=seed).std(axis=0)
                                      for f in features for seed in seeds], axis=0)
        self.noise_spread_ = np.where(self.noise_spread_ > 0, self.noise_spread_, 1.0)
        pitch_spread = float(np.mean([self._followed_pitch(f, self.predicted_envelope(f)).std() for f in features]))
        self.pitch_prediction_spread_ = pitch_spread if pitch_spread > 0 else 1.0
        # the average over recordings of generated / recorded spread is 1 on every axis
        ratios = np.mean([self._motion(f, seed=seed).std(axis=0) / (spread / RADIANS_PER_AU)
                          for f, spread in zip(features, spreads, strict=True) for seed in seeds], axis=0)
        self.output_scale_ = np.where(ratios > 0, 1.0 / np.where(ratios > 0, ratios, 1.0), 1.0)
        names = list(names) if names is not None else [f"recording {i}" for i in range(len(features))]
        self.training_ = [TrainingClip.of(name, f.n_frames, fps, f.source)
                          for name, f in zip(names, features, strict=False)]
        return self

    # generation -----------------------------------------------------------------------------------------
    def _linear(self, features: Features, columns: tuple[int, ...], weights: np.ndarray, mean: np.ndarray,
                spread: np.ndarray) -> np.ndarray:
        """A fitted regression on the windowed features, summed offset by offset: the same numbers as the
        design matrix times the weights, in memory proportional to the recording, not to the window."""
        per_frame = prosodic_features(features)[:, columns]
        n = per_frame.shape[0]
        smooth = np.column_stack([centred_moving_average(per_frame[:, j], self._smoothing(features.fps))
                                  for j in range(per_frame.shape[1])]) if n else per_frame
        width = per_frame.shape[1]
        index = np.arange(n)
        total = np.full(n, float(weights[-1]))
        for block, offset in enumerate(self.offsets_frames(features.fps)):
            part = slice(block * width, (block + 1) * width)
            scaled = weights[part] / spread[part]
            total += smooth[np.clip(index + offset, 0, max(n - 1, 0))] @ scaled - float(mean[part] @ scaled)
        return total

    def regression_residuals(self, features: Features, motion_au: np.ndarray) -> dict[str, np.ndarray]:
        """Residuals of the two fitted regressions on one recording: the speed envelope (relative to its mean)
        and the pitch (in units of its spread), recorded less predicted, before any gating."""
        from ...dsp import lowpass_head, speed_envelope

        self._check_fitted()
        radians = np.asarray(motion_au, float) * RADIANS_PER_AU
        envelope = speed_envelope(radians, fps=self.fps_)
        pitch = lowpass_head(radians, fps=self.fps_)[:, 0]
        envelope = envelope / envelope.mean() if envelope.mean() > 0 else envelope
        pitch = (pitch - pitch.mean()) / pitch.std() if pitch.std() > 0 else pitch
        return {
            "speed_envelope": envelope - self._linear(features, ENVELOPE_FEATURES, self.envelope_weights_,
                                                      self.envelope_mean_, self.envelope_std_),
            "pitch": pitch - self._linear(features, PITCH_FEATURES, self.pitch_weights_, self.pitch_mean_,
                                          self.pitch_std_),
        }

    def predicted_envelope(self, features: Features) -> np.ndarray:
        """Predicted head speed relative to the average while speaking (1 = average), with the idle floor
        and the fall to idle where there is no speech; shape (n_frames,)."""
        relative = self._linear(features, ENVELOPE_FEATURES, self.envelope_weights_, self.envelope_mean_,
                                self.envelope_std_)
        presence = speech_presence(features)
        relative = np.maximum(relative, self.idle_ratio)
        if self.envelope_power != 1.0:
            relative = np.maximum(relative**self.envelope_power, self.idle_ratio)
        return self.idle_ratio + (relative - self.idle_ratio) * presence

    def predicted_pitch(self, features: Features) -> np.ndarray:
        """Predicted head pitch in units of its recorded spread, about the average pose while speaking (0),
        fading to 0 (rest) where there is no speech; shape (n_frames,)."""
        predicted = self._linear(features, PITCH_FEATURES, self.pitch_weights_, self.pitch_mean_, self.pitch_std_)
        return predicted * speech_presence(features)

    def _followed_pitch(self, features: Features, envelope: np.ndarray) -> np.ndarray:
        """The predicted pitch as the head follows it (:func:`follow`, ``pitch_follow_s`` at the average of
        the predicted ``envelope``), in units of the recorded spread."""
        pitch = self.predicted_pitch(features)
        if self.pitch_follow_s <= 0 or pitch.size == 0:
            return pitch
        return follow(pitch, envelope / max(float(envelope.mean()), 1e-12), frames=self.pitch_follow_s * self.fps_)

    def _noise_angles(self, features: Features, *, seed: int) -> np.ndarray:
        """Coloured noise (n_frames, 3), rad, whose speed follows the predicted envelope, leaking to rest."""
        n = features.n_frames
        fps = self.fps_
        taps = self.filters_.shape[1]
        generator = np.random.default_rng(seed)
        white = generator.standard_normal((n + taps - 1, len(HEAD_FAPS)))
        shaped = np.column_stack([np.convolve(white[:, axis], self.filters_[axis], mode="valid")
                                  for axis in range(len(HEAD_FAPS))])
        velocity = shaped * self.velocity_scale_  # rad/s, the recorded spread per axis
        # the speed a viewer sees is the smooth one (below 4 Hz): that is what follows the envelope
        own_speed = centred_moving_average(np.sqrt((zero_phase_lowpass(velocity, fps=fps) ** 2).sum(axis=1)),
                                           int(round(SPEED_ENVELOPE_S * fps)))
        wanted_speed = self.predicted_envelope(features) * self.speed_rad_s_
        velocity *= (wanted_speed / np.maximum(own_speed, 1e-12))[:, None]
        angles = np.empty_like(velocity)
        for axis in range(len(HEAD_FAPS)):
            # the pitch axis's noise only adds the quick part of the motion; its slow part is the prediction
            leak_s = self.pitch_leak_s if axis == 0 else self.leak_s
            decay = math.exp(-1.0 / (leak_s * fps))
            # the leaky integral y[t] = decay * y[t-1] + v[t] / fps, as a convolution with decay^k
            reach = min(n, int(math.ceil(12 * leak_s * fps)) + 1)
            kernel = decay ** np.arange(reach) / fps
            angles[:, axis] = _causal_convolve(velocity[:, axis:axis + 1], kernel)[:, 0]
        return angles

    def _motion(self, features: Features, *, seed: int) -> np.ndarray:
        """Head angles (n_frames, 3) in AU: noise on every axis, the predicted pitch mixed into the first,
        the noise's speed then corrected so that the whole head's speed follows the prediction."""
        if features.n_frames == 0:
            return np.zeros((0, len(HEAD_FAPS)))
        noise = self._noise_angles(features, seed=seed) / self.noise_spread_  # unit spread per axis
        envelope = self.predicted_envelope(features)
        pitch = self._followed_pitch(features, envelope) / self.pitch_prediction_spread_  # unit spread
        share = self.pitch_share
        noise[:, 0] *= math.sqrt(max(0.0, 1.0 - share**2))
        scale = self.spread_au_ * self.output_scale_ * RADIANS_PER_AU
        fixed = np.zeros_like(noise)
        fixed[:, 0] = share * pitch
        wanted = envelope / max(float(envelope.mean()), 1e-12)
        for _ in range(self.speed_iterations):
            # the pitch prediction moves the head too: rescale the noise until the sum has the wanted speed
            speed = smooth_speed_envelope((fixed + noise) * scale, fps=self.fps_)
            speed = speed / max(float(speed.mean()), 1e-12)
            noise *= np.clip(wanted / np.maximum(speed, 1e-12), 0.25, 4.0)[:, None]
        motion = (fixed + noise) * scale / RADIANS_PER_AU
        if self.burst_power > 0:
            motion = shape_head(motion, fps=self.fps_, expressivity=Expressivity(power=self.burst_power))
        return motion

    #: The motion depends on the seed (its coloured noise).
    stochastic: ClassVar[bool] = True

    def rest_pose_au(self) -> np.ndarray:
        """The pose the motion is about: the rest pose itself, AU (3,) of zeros."""
        return np.zeros(len(HEAD_FAPS))

    def generate(self, features: Features, *, seed: int = 0) -> dict[int, np.ndarray]:
        """Head motion for a recording: FAP number (48, 49, 50) -> curve in AU. Same seed, same motion."""
        self._check_fitted()
        if features.fps != self.fps_:
            raise ConfigError(
                f"the model was trained at {self.fps_:g} fps but the features are at {features.fps:g} fps; "
                "extract features at the model's rate or train a model at this rate"
            )
        motion = self._motion(features, seed=valid_seed(seed))
        return {fap: motion[:, axis] for axis, fap in enumerate(HEAD_FAPS)}

    def _check_fitted(self) -> None:
        if not hasattr(self, "filters_"):
            raise ConfigError("the model is not fitted: call fit() or load a model file")

    # persistence ----------------------------------------------------------------------------------------
    SETTINGS = OfflineHeadSettings.setting_names()
    #: settings that files written before they existed leave out, with the value that reproduces those files
    OPTIONAL_SETTINGS = {"envelope_power": 1.0, "burst_power": 0.0, "pitch_follow_s": 0.0}

    def _array_shapes(self) -> dict[str, tuple[int, ...]]:
        fps = getattr(self, "fps_", 30.0)
        width = len(self.offsets_frames(fps))
        axes = len(HEAD_FAPS)
        return {
            "envelope_weights": (len(ENVELOPE_FEATURES) * width + 1,),
            "envelope_mean": (len(ENVELOPE_FEATURES) * width,), "envelope_std": (len(ENVELOPE_FEATURES) * width,),
            "pitch_weights": (len(PITCH_FEATURES) * width + 1,),
            "pitch_mean": (len(PITCH_FEATURES) * width,), "pitch_std": (len(PITCH_FEATURES) * width,),
            "filters": (axes, SPECTRUM_FRAMES), "velocity_scale": (axes,), "spread_au": (axes,),
            "noise_spread": (axes,), "output_scale": (axes,),
        }

    def to_dict(self) -> dict:
        """The model as plain data (what :meth:`save` writes)."""
        self._check_fitted()
        return {
            "format": MODEL_FORMAT,
            "version": MODEL_VERSION,
            "kind": MODEL_KIND,
            "fps": self.fps_,
            "settings": {name: getattr(self, name) for name in self.SETTINGS},
            "features": list(FEATURE_NAMES),
            "envelope_features": [FEATURE_NAMES[i] for i in ENVELOPE_FEATURES],
            "pitch_features": [FEATURE_NAMES[i] for i in PITCH_FEATURES],
            "outputs": list(HEAD_FAPS),
            **{key: np.asarray(getattr(self, key + "_")).tolist() for key in self._array_shapes()},
            "speed_rad_s": self.speed_rad_s_,
            "pitch_prediction_spread": self.pitch_prediction_spread_,
            "training": [clip.__dict__ for clip in self.training_],
        }

    @classmethod
    def from_dict(cls, payload: object, *, source: str = "<dict>") -> ProsodicHeadModel:
        """Rebuild a model from :meth:`to_dict` output, checking every field."""

        def check_settings(settings: dict, fail: Callable[[str], ModelError]) -> None:
            for name, value in settings.items():
                if not finite_number(value):
                    raise fail(f"setting {name!r} must be a finite number, got {value!r}")
            if not isinstance(settings["speed_iterations"], int):
                raise fail(f"setting 'speed_iterations' must be a whole number, got {settings['speed_iterations']!r}")

        return read_prosodic_model(
            cls, payload, source=source, kind=MODEL_KIND,
            unsupported=f"is not supported (this release reads version {MODEL_VERSION} of kind {MODEL_KIND!r})",
            check_settings=check_settings,
            names={"features": list(FEATURE_NAMES), "outputs": list(HEAD_FAPS),
                   "envelope_features": [FEATURE_NAMES[i] for i in ENVELOPE_FEATURES],
                   "pitch_features": [FEATURE_NAMES[i] for i in PITCH_FEATURES]})
