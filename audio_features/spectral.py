"""Spectral features on the frame grid: mel-frequency cepstral coefficients and log energy.

The short-time spectrum of 25 ms Hann windows every 10 ms is pooled by a 40-band mel filterbank (librosa's
default one, Slaney's, 50-7600 Hz, the bands of speech recognisers), logged, and turned into 13 cepstral
coefficients by a DCT; with the log energy they describe the vocal tract's shape, which the mouth is part of.
The 10 ms frames are then read at any grid time by the nearest one.
"""

from __future__ import annotations

import os

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


def _hz_to_mel(hz: np.ndarray | float) -> np.ndarray:
    """Slaney's mel scale (librosa's default): linear below 1 kHz (200/3 Hz a mel), logarithmic above."""
    hz = np.asarray(hz, float)
    linear = hz / (200.0 / 3)
    return np.where(hz >= 1000.0, 15.0 + np.log(np.maximum(hz, 1e-10) / 1000.0) / (np.log(6.4) / 27.0), linear)


def _mel_to_hz(mel: np.ndarray | float) -> np.ndarray:
    mel = np.asarray(mel, float)
    return np.where(mel >= 15.0, 1000.0 * np.exp((np.log(6.4) / 27.0) * (mel - 15.0)), mel * (200.0 / 3))


def mel_filterbank(rate: int, n_fft: int, n_mels: int, low_hz: float, high_hz: float) -> np.ndarray:
    """Triangular filters evenly spaced on Slaney's mel scale, each of unit area (Slaney's normalisation),
    float32, shape ``(n_mels, n_fft // 2 + 1)``: the filterbank of ``librosa.filters.mel`` with its defaults,
    built here so that the live path does not import librosa (and numba: about 130 MB).

    Parameters
    ----------
    rate : int
        Sample rate, Hz.
    n_fft : int
        FFT length.
    n_mels : int
        Number of filters.
    low_hz, high_hz : float
        The band the filters cover.

    Returns
    -------
    numpy.ndarray
    """
    edges = _mel_to_hz(np.linspace(_hz_to_mel(low_hz), _hz_to_mel(high_hz), n_mels + 2))
    bins = np.fft.rfftfreq(n_fft, 1.0 / rate)
    widths = np.diff(edges)
    ramps = np.subtract.outer(edges, bins)
    weights = np.zeros((n_mels, bins.size), dtype=np.float32)
    for i in range(n_mels):
        weights[i] = np.maximum(0, np.minimum(-ramps[i] / widths[i], ramps[i + 2] / widths[i + 1]))
    weights *= (2.0 / (edges[2:n_mels + 2] - edges[:n_mels]))[:, None]
    return weights


def _analysis(rate: int) -> tuple[int, int, np.ndarray, np.ndarray]:
    """FFT size, window length, taper and mel filterbank of the analysis at ``rate``."""
    if rate < 8000:
        raise ParameterError(f"sample rate {rate} Hz is below 8000 Hz")
    window = int(round(WINDOW_S * rate))
    n_fft = 1 << (window - 1).bit_length()
    taper = np.zeros(n_fft)
    taper[(n_fft - window) // 2:(n_fft - window) // 2 + window] = np.hanning(window)
    mel = mel_filterbank(rate, n_fft, N_MELS, MEL_LOW_HZ, min(MEL_HIGH_HZ, 0.475 * rate))
    return n_fft, window, taper, mel


def _dct_rows(n_in: int, n_out: int) -> np.ndarray:
    """The first ``n_out`` rows of the orthonormal DCT-II of length ``n_in`` (``scipy.fft.dct(x, type=2,
    norm="ortho")[:n_out] == _dct_rows(n_in, n_out) @ x``), as a matrix: the live path then needs no scipy."""
    k = np.arange(n_out)[:, None]
    rows = np.sqrt(2.0 / n_in) * np.cos(np.pi * k * (2 * np.arange(n_in) + 1) / (2 * n_in))
    rows[0] /= np.sqrt(2.0)
    return rows


_DCT = _dct_rows(N_MELS, N_CEPSTRA)


def _cepstra_of(frames: np.ndarray, taper: np.ndarray, mel: np.ndarray) -> np.ndarray:
    """Cepstra and log energy of windows (rows of ``frames``)."""
    power = np.abs(np.fft.rfft(frames * taper, axis=1)) ** 2
    log_mel = np.log(power @ mel.T + 1e-10)
    out = np.empty((frames.shape[0], N_SPECTRAL))
    out[:, :N_CEPSTRA] = log_mel @ _DCT.T
    out[:, N_CEPSTRA] = np.log(power.mean(axis=1) + 1e-10)
    return out


def cepstra(audio: Audio) -> np.ndarray:
    """MFCCs and log energy of every 10 ms frame, shape (n, 14); frame ``j`` is centred at ``j / 100`` s.

    Parameters
    ----------
    audio : Audio
        The recording (mono).

    Returns
    -------
    numpy.ndarray
        (n, 14): 13 MFCCs and the log energy per frame.

    Examples
    --------
    >>> t = np.arange(16000) / 16000
    >>> cepstra(Audio(0.5 * np.sin(2 * np.pi * 200 * t), 16000)).shape
    (101, 14)
    """
    rate = audio.sample_rate_hz
    n_fft, _, taper, mel = _analysis(rate)
    hop = rate / CEPSTRUM_RATE
    n = int(audio.samples.size / hop) + 1
    padded = np.pad(audio.samples, (n_fft // 2, n_fft))
    starts = np.round(np.arange(n) * hop).astype(int)
    out = np.empty((n, N_SPECTRAL))
    for first in range(0, n, 4096):  # blocks: memory stays bounded on long recordings
        chunk = starts[first:first + 4096]
        out[first:first + chunk.size] = _cepstra_of(padded[chunk[:, None] + np.arange(n_fft)], taper, mel)
    return out


class CepstraStream:
    """The frames of :func:`cepstra` for audio that arrives piece by piece: each as soon as its window is in,
    the same values as the whole-recording analysis however the audio is cut.

    Parameters
    ----------
    sample_rate_hz : int
        Rate of the samples that will be pushed.

    Examples
    --------
    >>> t = np.arange(16000) / 16000
    >>> tone = 0.5 * np.sin(2 * np.pi * 200 * t)
    >>> live = CepstraStream(16000)
    >>> parts = [live.push(tone[i:i + 700]) for i in range(0, tone.size, 700)] + [live.finish()]
    >>> bool(np.allclose(np.vstack(parts), cepstra(Audio(tone, 16000))))
    True
    """

    def __init__(self, sample_rate_hz: int) -> None:
        self.sample_rate_hz = int(sample_rate_hz)
        self._n_fft, _, self._taper, self._mel = _analysis(self.sample_rate_hz)
        self._hop = self.sample_rate_hz / CEPSTRUM_RATE
        self._buffer = np.zeros(self._n_fft // 2)  # the zeros before the start, as the whole analysis pads
        self._buffer_start = -(self._n_fft // 2)  # absolute index of the buffer's first sample
        self._received = 0
        self._next = 0

    @property
    def latency_s(self) -> float:
        """Audio needed after a frame's centre before it can be computed."""
        return (self._n_fft // 2) / self.sample_rate_hz

    def _start(self, j: int) -> int:
        return int(np.round(j * self._hop)) - self._n_fft // 2

    def _take(self, end_frame: int) -> np.ndarray:
        frames = []
        while self._next < end_frame:
            start = self._start(self._next) - self._buffer_start
            frames.append(self._buffer[start:start + self._n_fft])
            self._next += 1
        out = _cepstra_of(np.array(frames), self._taper, self._mel) if frames else np.zeros((0, N_SPECTRAL))
        keep_from = self._start(self._next) - self._buffer_start
        if keep_from > 0:
            self._buffer = self._buffer[keep_from:]
            self._buffer_start += keep_from
        return out

    def push(self, samples: np.ndarray) -> np.ndarray:
        """Add mono samples; return the frames that became complete, shape (k, 14).

        Parameters
        ----------
        samples : numpy.ndarray
            Mono samples at the stream's rate.

        Returns
        -------
        numpy.ndarray
        """
        samples = np.asarray(samples, float).reshape(-1)
        self._buffer = np.concatenate([self._buffer, samples])
        self._received += samples.size
        end = self._next
        while self._start(end) + self._n_fft <= self._received:
            end += 1
        return self._take(end)

    def finish(self) -> np.ndarray:
        """The remaining frames, with silence after the end (as the whole analysis pads).

        Returns
        -------
        numpy.ndarray
            (k, 14).
        """
        total = int(self._received / self._hop) + 1
        self._buffer = np.concatenate([self._buffer, np.zeros(self._n_fft)])
        return self._take(total)


def on_grid(frames: np.ndarray, n_frames: int, *, fps: float, offset_s: float = 0.0) -> np.ndarray:
    """The 10 ms frames nearest to grid times ``k / fps + offset_s`` (held at the ends), shape (n_frames, 14).

    Parameters
    ----------
    frames : numpy.ndarray
        10 ms frames, (n, 14).
    n_frames : int
        Frames of the grid.
    fps : float
        Frames per second of the grid.
    offset_s : float
        A shift of every grid time, in s.

    Returns
    -------
    numpy.ndarray
    """
    if not (np.isfinite(fps) and fps > 0):
        raise ParameterError(f"fps must be a positive number, got {fps!r}")
    index = np.round((np.arange(n_frames) / fps + offset_s) * CEPSTRUM_RATE).astype(int)
    return frames[np.clip(index, 0, frames.shape[0] - 1)]


def file_cepstra(source: Audio | str | os.PathLike[str]) -> np.ndarray:
    """:func:`cepstra` of a recording, a file read block by block (bounded memory for any length).

    Parameters
    ----------
    source : Audio or path-like
        The recording, in memory or a file.

    Returns
    -------
    numpy.ndarray
        (n, 14), as :func:`cepstra`.
    """
    if isinstance(source, Audio):
        return cepstra(source)
    from .audio import file_blocks

    rate, blocks = file_blocks(source)
    stream = CepstraStream(rate)
    return np.vstack([stream.push(block) for block in blocks] + [stream.finish()])
