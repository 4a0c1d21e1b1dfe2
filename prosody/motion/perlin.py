"""Fractal Perlin noise: the RANDOM baseline of docs/models.md."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..fap.table import EYEBROW_FAPS
from ..validate import valid_seed

#: Per-clip standard deviation of head rotation in ../shared/data/talking-heads (median pose removed),
#: averaged over its seven clips, in AU: pitch 4281, yaw 7196, roll 5437.
HEAD_STD_AU = {48: 4300.0, 49: 7200.0, 50: 5400.0}
#: Inner-eyebrow spread used for the RANDOM brows, in ENS (the thesis's recorded subjects: 5 to 17 ENS;
#: its Perlin brows for subjects S2 and S7: 11.6 and 13.5).
EYEBROW_STD_ENS = 10.0
#: Frame offset of each head axis into the noise (the thesis's way of decorrelating the axes; each channel
#: also has its own lattice, so they are independent).
HEAD_OFFSETS_FRAMES = {48: 0.0, 49: 7919.0, 50: 15838.0}
#: Lattice key of each channel: the brows and each head axis draw from their own noise.
CHANNEL_KEYS = {"brows": 1, 48: 48, 49: 49, 50: 50}
_MASK64 = (1 << 64) - 1


@dataclass(frozen=True)
class PerlinSettings:
    """Fractal noise: ``sum_i persistence**i * noise(base_frequency * 2**i * x)``, x in frames.

    Parameters
    ----------
    octaves : int >= 1
        Number of octaves (thesis: 6).
    persistence : float > 0
        Amplitude ratio between successive octaves (thesis: 0.8).
    base_frequency_hz : float > 0, in Hz
        Frequency of the first octave; octave i runs at ``base * 2**i`` (0.4 Hz gives 0.4 .. 12.8 Hz).
    """

    octaves: int = 6
    persistence: float = 0.8
    base_frequency_hz: float = 0.4

    def __post_init__(self) -> None:
        if not (isinstance(self.octaves, int) and self.octaves >= 1):
            raise ConfigError(f"octaves must be a whole number >= 1, got {self.octaves!r}")
        if not self.persistence > 0 or not self.base_frequency_hz > 0:
            raise ConfigError("persistence and base_frequency_hz must be positive")


def _mix64(values: np.ndarray) -> np.ndarray:
    """SplitMix64's finaliser on uint64 values: every input bit changes about half of the output bits."""
    z = values.copy()
    z ^= z >> np.uint64(30)
    z *= np.uint64(0xBF58476D1CE4E5B9)
    z ^= z >> np.uint64(27)
    z *= np.uint64(0x94D049BB133111EB)
    z ^= z >> np.uint64(31)
    return z


def _lattice_key(seed: int, channel: int) -> np.uint64:
    """A 64-bit key per (seed, channel): different channels, and different seeds, get unrelated lattices."""
    mixed = _mix64(np.array([(seed * 0x9E3779B97F4A7C15 + channel) & _MASK64], dtype=np.uint64))
    return np.uint64(int(mixed[0]))


def _gradients(cells: np.ndarray, key: np.uint64) -> np.ndarray:
    """The gradient (-1 .. 1) at each lattice cell: a hash of the cell and the key, so the lattice never
    repeats (a table of gradients would, after as many cells as it holds)."""
    hashed = _mix64(cells.astype(np.uint64) * np.uint64(0x9E3779B97F4A7C15) + key)
    return (hashed >> np.uint64(11)).astype(np.float64) * (2.0 / 2.0**53) - 1.0


def _gradient_noise(x: np.ndarray, key: np.uint64) -> np.ndarray:
    """Classic 1-D Perlin gradient noise: 0 at every lattice point, smooth (quintic fade) between."""
    cell = np.floor(x)
    frac = x - cell
    cells = cell.astype(np.int64)
    g0 = _gradients(cells, key)
    g1 = _gradients(cells + 1, key)
    fade = frac**3 * (frac * (frac * 6 - 15) + 10)
    return (1 - fade) * g0 * frac + fade * g1 * (frac - 1)


def fractal_noise(n_frames: int, *, fps: float, seed: int, offset_frames: float = 0.0,
                  settings: PerlinSettings | None = None, channel: int = 0) -> np.ndarray:
    """Fractal Perlin noise at frames ``0..n_frames-1`` (shifted by ``offset_frames``), unscaled.

    The same ``seed`` and ``channel`` give the same values, bit for bit; the lattice gradients are a hash
    of the lattice cell, the seed and the channel, so channels are independent and the noise never repeats.
    """
    settings = settings or PerlinSettings()
    key = _lattice_key(valid_seed(seed), int(channel))
    x = np.arange(n_frames, dtype=float) + offset_frames
    total = np.zeros(n_frames)
    for octave in range(settings.octaves):
        frequency = settings.base_frequency_hz / fps * 2**octave  # cycles per frame
        total += settings.persistence**octave * _gradient_noise(x * frequency + 0.5 * octave, key)
    return total


def _scaled(curve: np.ndarray, target_std: float) -> np.ndarray:
    spread = curve.std()
    return curve * (target_std / spread) if spread > 1e-12 else np.zeros_like(curve)


def perlin_curves(n_frames: int, *, fps: float, seed: int = 0, settings: PerlinSettings | None = None,
                  eyebrow_std_ens: float = EYEBROW_STD_ENS,
                  head_std_au: dict[int, float] | None = None) -> dict[int, np.ndarray]:
    """RANDOM prosody FAPs: brows from non-negative noise, head axes from signed noise, each channel from
    its own noise (the brows do not follow the head).

    Each curve is scaled so that its standard deviation over the stream equals the target (for the brows,
    after the negatives are dropped): real motion's spread, so the baseline moves as much as people do.

    Returns
    -------
    dict
        FAP number -> curve of shape (n_frames,): 31-34 in ENS (31 = 32, 33 = 34), 48-50 in AU.

    Examples
    --------
    >>> curves = perlin_curves(300, fps=30, seed=1)
    >>> round(float(curves[48].std()))
    4300
    >>> bool((curves[31] >= 0).all())
    True
    """
    head_std_au = head_std_au or HEAD_STD_AU
    brows = np.maximum(fractal_noise(n_frames, fps=fps, seed=seed, settings=settings,
                                     channel=CHANNEL_KEYS["brows"]), 0.0)
    brows = _scaled(brows, eyebrow_std_ens)
    curves = {fap: brows.copy() for fap in EYEBROW_FAPS}
    for fap, offset in HEAD_OFFSETS_FRAMES.items():
        head = fractal_noise(n_frames, fps=fps, seed=seed, offset_frames=offset, settings=settings,
                             channel=CHANNEL_KEYS[fap])
        curves[fap] = _scaled(head - head.mean(), head_std_au[fap])
    return curves
