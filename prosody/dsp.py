"""Signal processing on the frame grid that measures and generators share: the zero-phase low-pass of head
angles, centred moving averages, and the head's angular speed and its envelope (as docs/evaluation.md defines them).

Examples
--------
>>> t = np.arange(300) / 30
>>> turning = np.column_stack([np.radians(10) * t, 0 * t, 0 * t])  # 10 degrees a second about one axis
>>> round(float(np.degrees(np.median(speed_envelope(turning, fps=30.0)))), 3)
10.0
"""

from __future__ import annotations

import numpy as np

#: Low-pass cut-off applied to head angles before any velocity: above ~5 Hz recordings are tracker jitter.
HEAD_LOWPASS_HZ = 4.0
#: Window of the centred moving average that turns head speed into its envelope, in s.
SPEED_ENVELOPE_S = 0.5


def lowpass_head(angles_rad: np.ndarray, *, fps: float, cutoff_hz: float = HEAD_LOWPASS_HZ) -> np.ndarray:
    """Head angles low-passed by a 4th-order Butterworth filter run forwards and backwards (zero phase).

    Parameters
    ----------
    angles_rad : array (n_frames,) or (n_frames, n_axes)
    fps : float > 0
    cutoff_hz : float > 0, in Hz
        Left unfiltered when at or above the Nyquist frequency, or when the curve is too short to filter.
    """
    from scipy.signal import butter, sosfiltfilt

    angles = np.asarray(angles_rad, float)
    if cutoff_hz >= fps / 2:
        return angles.copy()
    sos = butter(4, cutoff_hz, btype="low", fs=fps, output="sos")
    pad = 3 * (2 * sos.shape[0] + 1)
    if angles.shape[0] <= pad:
        return angles.copy()
    return sosfiltfilt(sos, angles, axis=0)


def centred_moving_average(values: np.ndarray, window: int) -> np.ndarray:
    """Centred moving average over ``window`` frames (odd windows are symmetric), edges padded with the
    edge value.

    Examples
    --------
    >>> centred_moving_average(np.array([0.0, 0.0, 3.0, 0.0, 0.0]), 3).tolist()
    [0.0, 1.0, 1.0, 1.0, 0.0]
    """
    values = np.asarray(values, float)
    window = max(1, int(window))
    before = window // 2
    after = window - 1 - before
    padded = np.concatenate([np.full(before, values[0]), values, np.full(after, values[-1])])
    cumulative = np.concatenate([[0.0], np.cumsum(padded)])
    return (cumulative[window:] - cumulative[:-window]) / window


def head_speed(angles_rad: np.ndarray, *, fps: float) -> np.ndarray:
    """Angular speed (rad/s): the norm of the three axes' velocities, by central differences, of the
    4 Hz low-passed angles; shape (n_frames,)."""
    smooth = lowpass_head(np.asarray(angles_rad, float), fps=fps)
    if smooth.shape[0] < 2:
        return np.zeros(smooth.shape[0])
    velocity = np.gradient(smooth, axis=0) * fps
    return np.sqrt((velocity**2).sum(axis=1)) if velocity.ndim == 2 else np.abs(velocity)


def speed_envelope(angles_rad: np.ndarray, *, fps: float, window_s: float = SPEED_ENVELOPE_S) -> np.ndarray:
    """How much the head is moving: its speed averaged over a centred 0.5 s window (rad/s)."""
    return centred_moving_average(head_speed(angles_rad, fps=fps), int(round(window_s * fps)))
