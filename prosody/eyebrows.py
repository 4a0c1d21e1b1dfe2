"""The eyebrow rule of SPEC section 3: raise on a rising F0 crossing, hold, release when the voice fades."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from audio_features import Features

from .errors import ConfigError


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
        if not self.threshold_hz > 0:
            raise ConfigError(f"threshold_hz must be positive, got {self.threshold_hz!r}")
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


@dataclass(frozen=True)
class EyebrowRaises:
    """Result of the rule: the displacement (ENS) per frame and the raise events.

    ``events`` holds ``(onset_frame, release_frame)`` pairs: the raise starts at ``onset_frame`` and the
    ramp back to neutral starts at ``release_frame`` (``n_frames`` if the recording ends raised).
    """

    displacement_ens: np.ndarray
    events: tuple[tuple[int, int], ...]
    f0_threshold_hz: float
    energy_threshold_db: float

    def curves(self) -> dict[int, np.ndarray]:
        """FAP 31 = 32 (inner) and 33 = 34 (middle): both sides and both points move together."""
        return {fap: self.displacement_ens.copy() for fap in (31, 32, 33, 34)}


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
    A 150 Hz tone that jumps to 250 Hz raises the brows at the jump (frame 15 at 30 fps):

    >>> import numpy as np
    >>> from audio_features import Audio, extract_features
    >>> t = np.arange(16000) / 16000
    >>> f0 = np.where(t < 0.5, 150.0, 250.0)
    >>> tone = 0.5 * np.sin(2 * np.pi * np.cumsum(f0) / 16000)
    >>> eyebrow_raises(extract_features(Audio(tone, 16000))).events[0][0]
    15
    """
    rule = rule or EyebrowRule()
    f0 = features.f0_conditioned.values
    energy = features.energy.values
    n = f0.shape[0]
    threshold_hz = rule.f0_threshold_hz(features)
    threshold_db = rule.energy_threshold(features)
    hold_frames = int(round(rule.min_hold_s * features.fps))  # 300 ms -> 9 frames at 30 fps
    # rising edge: F0[k-1] < threshold <= F0[k] (SPEC section 3)
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
    return EyebrowRaises(out, tuple(events), threshold_hz, threshold_db)
