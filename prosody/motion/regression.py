"""What both prosodic head fits (offline and live) compute alike: ridge regressions on standardised columns,
the noise-shaping filters that give generated motion the recorded motion's spectrum, the fit of their timing
(:class:`TimingFit`), and the check of a model file's numbers.

Examples
--------
>>> import numpy as np
>>> x = np.arange(10.0)[:, None]
>>> weights, mean, spread = ridge_fit(x, 2 * x[:, 0] + 1, 0.0)
>>> [round(float(w), 6) for w in weights / [spread[0], 1]], float(mean[0])
([2.0, 10.0], 4.5)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import NamedTuple

import numpy as np

from ..errors import ConfigError
from ..fap.table import HEAD_FAPS, RADIANS_PER_AU
from .model_files import MAX_MODEL_MAGNITUDE

#: Taps of the noise-shaping filters (the recorded velocity's spectrum is estimated on this many frames).
SPECTRUM_FRAMES = 128
#: Shortest recording whose velocity spectrum is estimated.
MIN_SPECTRUM_FRAMES = 16


def ridge_fit(x: np.ndarray, y: np.ndarray, penalty: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ridge regression on standardised columns, the intercept not shrunk.

    Parameters
    ----------
    x : numpy.ndarray
        Inputs, (n_samples, n_columns).
    y : numpy.ndarray
        Targets, (n_samples,) or (n_samples, n_targets).
    penalty : float
        Ridge penalty per standardised column.

    Returns
    -------
    weights, mean, spread : numpy.ndarray
        The weights (intercept last), and each column's mean and spread (1 where a column is constant).
    """
    mean = x.mean(axis=0)
    spread = x.std(axis=0)
    spread = np.where(spread > 1e-12, spread, 1.0)
    z = np.hstack([(x - mean) / spread, np.ones((x.shape[0], 1))])
    shrink = np.eye(z.shape[1]) * penalty
    shrink[-1, -1] = 0.0  # the intercept is not shrunk
    weights = np.linalg.solve(z.T @ z + shrink, z.T @ y)
    return weights, mean, spread



def shaping_filter(velocities: Sequence[np.ndarray], fps: float) -> np.ndarray:
    """Zero-phase FIR taps whose gain follows the average amplitude spectrum of the given velocity curves
    (each recording weighted equally), normalised to unit output variance for unit white noise."""
    from scipy.signal import welch

    spectra = []
    for velocity in velocities:
        if velocity.size < MIN_SPECTRUM_FRAMES:
            continue
        # short recordings give a coarser estimate on the same frequency grid
        _, power = welch(velocity, fs=fps, nperseg=min(SPECTRUM_FRAMES, velocity.size), nfft=SPECTRUM_FRAMES)
        total = power.sum()
        if total > 0:
            spectra.append(power / total)
    if not spectra:
        raise ConfigError(f"head motion too short to estimate its spectrum (need {MIN_SPECTRUM_FRAMES} frames)")
    # the geometric mean over recordings: the spectrum is judged in dB, where one jittery recording would
    # otherwise dominate an arithmetic mean
    amplitude = np.sqrt(np.exp(np.mean(np.log(np.maximum(spectra, 1e-30)), axis=0)))
    taps = np.fft.fftshift(np.fft.irfft(amplitude, n=SPECTRUM_FRAMES))
    taps = taps * np.hanning(SPECTRUM_FRAMES + 1)[:SPECTRUM_FRAMES]
    return taps / np.sqrt(np.sum(taps**2))



def finite_number(value: object) -> bool:
    """A JSON number within :data:`MAX_MODEL_MAGNITUDE` (not a bool, not NaN or infinity)."""
    return (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
            and abs(value) <= MAX_MODEL_MAGNITUDE)


class TimingFit:
    """The fit both prosodic heads share (the offline generator and the live head): per recording, the relative
    speed envelope and the head pitch (in its spread) their regressions predict, and the motion's velocities,
    speed and spread that size their synthesis; then the two ridge regressions, the shaping filters and the
    speeds, set on the model.

    Parameters
    ----------
    fps : float
        The recordings' frame rate.
    """

    def __init__(self, fps: float) -> None:
        self.fps = fps
        self.envelope_rows: list[np.ndarray] = []
        self.envelope_targets: list[np.ndarray] = []
        self.pitch_rows: list[np.ndarray] = []
        self.pitch_targets: list[np.ndarray] = []
        self.velocities: list[np.ndarray] = []
        self.speeds: list[float] = []
        self.spreads: list[np.ndarray] = []

    def add(self, motion_au: np.ndarray, n_frames: int,
            designs: Callable[[], tuple[np.ndarray, np.ndarray]]) -> bool:
        """Add one recording: its head motion (``n_frames``, 3) in AU about its rest pose, and ``designs``, which
        gives its two regressions' design rows (envelope, pitch). A still recording teaches nothing about timing:
        it is left out (False).

        Parameters
        ----------
        motion_au : numpy.ndarray
        n_frames : int
            The recording's frames of audio, which the motion must match.
        designs : callable
            Called only for a recording that moves.

        Returns
        -------
        bool
            Whether the recording was kept.
        """
        from ..dsp import lowpass_head, speed_envelope  # training may import scipy.signal

        motion = np.asarray(motion_au, float)
        if motion.shape != (n_frames, len(HEAD_FAPS)):
            raise ConfigError(f"a recording has {n_frames} frames of audio but motion of shape {motion.shape}; "
                              f"expected ({n_frames}, 3)")
        radians = motion * RADIANS_PER_AU
        envelope = speed_envelope(radians, fps=self.fps)
        pitch = lowpass_head(radians, fps=self.fps)[:, 0]
        if envelope.mean() <= 0 or pitch.std() <= 0:
            return False
        design_envelope, design_pitch = designs()
        self.envelope_rows.append(design_envelope)
        self.envelope_targets.append(envelope / envelope.mean())
        self.pitch_rows.append(design_pitch)
        self.pitch_targets.append((pitch - pitch.mean()) / pitch.std())
        self.velocities.append(np.diff(radians, axis=0))
        self.speeds.append(envelope.mean())
        self.spreads.append(radians.std(axis=0))
        return True

    def fit(self, ridge: float) -> TimingModel:
        """The two regressions, the shaping filters, the velocity scale and the speed of the recordings added.

        Parameters
        ----------
        ridge : float
            The regressions' penalty.

        Returns
        -------
        TimingModel
        """
        if not self.envelope_rows:
            raise ConfigError("every training recording is still: nothing to learn")
        return TimingModel(
            ridge_fit(np.vstack(self.envelope_rows), np.concatenate(self.envelope_targets), ridge),
            ridge_fit(np.vstack(self.pitch_rows), np.concatenate(self.pitch_targets), ridge),
            np.vstack([shaping_filter([v[:, axis] for v in self.velocities], self.fps)
                       for axis in range(len(HEAD_FAPS))]),
            np.sqrt(np.mean([np.mean(v**2, axis=0) for v in self.velocities], axis=0)) * self.fps,
            float(np.mean(self.speeds)))


class TimingModel(NamedTuple):
    """What :meth:`TimingFit.fit` gives: each regression's (weights, mean, spread), the shaping filters (3, k),
    the velocity scale per axis (rad/s) and the recorded speed (rad/s)."""

    envelope: tuple[np.ndarray, np.ndarray, np.ndarray]
    pitch: tuple[np.ndarray, np.ndarray, np.ndarray]
    filters: np.ndarray
    velocity_scale: np.ndarray
    speed_rad_s: float
