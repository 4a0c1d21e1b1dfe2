"""What both prosodic head fits (offline and live) compute alike: ridge regressions on standardised columns,
the noise-shaping filters that give generated motion the recorded motion's spectrum, and the check of a model
file's numbers.

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
from collections.abc import Sequence

import numpy as np

from ..errors import ConfigError
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
