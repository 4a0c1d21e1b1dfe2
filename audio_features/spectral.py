"""Spectral features on the frame grid: mel-frequency cepstral coefficients and log energy.

The short-time spectrum of 25 ms Hann windows every 10 ms is pooled by a 40-band mel filterbank (librosa's,
50-7600 Hz, the bands of speech recognisers), logged, and turned into 13 cepstral coefficients by a DCT;
with the log energy they describe the vocal tract's shape, which the mouth is part of. The 10 ms frames are
then read at any grid time by the nearest one.
"""

from __future__ import annotations

import numpy as np

from .audio import Audio
from .errors import ParameterError

#: Analysis rate of the cepstra, frames per second.
CEPSTRUM_RATE = 100
#: Analysis window, s.
WINDOW_S = 0.025
#: Mel bands and their range, Hz (the top is lowered to 0.475 of the sample rate for 8 kHz audio).
N_MELS, MEL_LOW_HZ, MEL_HIGH_HZ = 40, 50.0, 7600.0
#: Cepstral coefficients kept.
N_CEPSTRA = 13
#: Columns: c0..c12 and the log energy.
N_SPECTRAL = N_CEPSTRA + 1


def cepstra(audio: Audio) -> np.ndarray:
    """MFCCs and log energy of every 10 ms frame, shape (n, 14); frame ``j`` is centred at ``j / 100`` s.

    Examples
    --------
    >>> t = np.arange(16000) / 16000
    >>> cepstra(Audio(0.5 * np.sin(2 * np.pi * 200 * t), 16000)).shape
    (101, 14)
    """
    import librosa.filters
    from scipy.fft import dct

    rate = audio.sample_rate_hz
    if rate < 8000:
        raise ParameterError(f"sample rate {rate} Hz is below 8000 Hz")
    window = int(round(WINDOW_S * rate))
    n_fft = 1 << (window - 1).bit_length()
    hop = rate / CEPSTRUM_RATE
    n = int(audio.samples.size / hop) + 1
    padded = np.pad(audio.samples, (n_fft // 2, n_fft))
    starts = np.round(np.arange(n) * hop).astype(int)
    taper = np.zeros(n_fft)
    taper[(n_fft - window) // 2:(n_fft - window) // 2 + window] = np.hanning(window)
    mel = librosa.filters.mel(sr=rate, n_fft=n_fft, n_mels=N_MELS, fmin=MEL_LOW_HZ,
                              fmax=min(MEL_HIGH_HZ, 0.475 * rate))
    out = np.empty((n, N_SPECTRAL))
    for first in range(0, n, 4096):  # blocks: memory stays bounded on long recordings
        chunk = starts[first:first + 4096]
        frames = padded[chunk[:, None] + np.arange(n_fft)] * taper
        power = np.abs(np.fft.rfft(frames, axis=1)) ** 2
        log_mel = np.log(power @ mel.T + 1e-10)
        out[first:first + chunk.size, :N_CEPSTRA] = dct(log_mel, type=2, norm="ortho", axis=1)[:, :N_CEPSTRA]
        out[first:first + chunk.size, N_CEPSTRA] = np.log(power.mean(axis=1) + 1e-10)
    return out


def on_grid(frames: np.ndarray, n_frames: int, *, fps: float, offset_s: float = 0.0) -> np.ndarray:
    """The 10 ms frames nearest to grid times ``k / fps + offset_s`` (held at the ends), shape (n_frames, 14)."""
    if not (np.isfinite(fps) and fps > 0):
        raise ParameterError(f"fps must be a positive number, got {fps!r}")
    index = np.round((np.arange(n_frames) / fps + offset_s) * CEPSTRUM_RATE).astype(int)
    return frames[np.clip(index, 0, frames.shape[0] - 1)]
