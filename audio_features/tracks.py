"""Frame-grid tracks: values that carry their frame rate and unit with them.

The package has one time base: frame ``k`` of a track at ``fps`` frames per second is at ``k / fps`` seconds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import ParameterError


def _frozen_array(values: object, *, dtype: type, name: str) -> np.ndarray:
    array: np.ndarray = np.array(values, dtype=dtype, copy=True)
    if array.ndim != 1:
        raise ParameterError(f"{name} must be one-dimensional, got shape {array.shape!r}", parameter=name)
    array.flags.writeable = False
    return array


def frame_count(duration_s: float, *, fps: float) -> int:
    """Number of grid frames whose time ``k / fps`` lies inside ``[0, duration_s)``.

    Parameters
    ----------
    duration_s : float
        Length of the recording in seconds.
    fps : float
        Frames per second of the grid.

    Returns
    -------
    int
        0 for a duration of 0 or less.

    Examples
    --------
    >>> frame_count(3.1, fps=30)
    93
    """
    if duration_s <= 0:
        return 0
    return int(np.ceil(duration_s * fps - 1e-9))


# arrays inside: equality is identity (numpy's == is elementwise), so it stays hashable
@dataclass(frozen=True, eq=False)
class Track:
    """A scalar signal sampled on the frame grid.

    Parameters
    ----------
    values : array of shape (n_frames,)
        One value per frame; frame ``k`` is at ``k / fps`` seconds.
    fps : float > 0
        Frames per second.
    unit : str
        Unit of ``values`` (for example ``"Hz"`` or ``"dB"``).
    name : str
        What the track measures (for example ``"energy"``).
    """

    values: np.ndarray
    fps: float
    unit: str
    name: str

    def __post_init__(self) -> None:
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise ParameterError(f"fps must be a positive number, got {self.fps!r}")
        object.__setattr__(self, "values", _frozen_array(self.values, dtype=float, name=f"{self.name} values"))

    @property
    def n_frames(self) -> int:
        return int(self.values.shape[0])

    @property
    def times_s(self) -> np.ndarray:
        """Time of each frame in seconds, shape (n_frames,)."""
        return np.arange(self.n_frames) / self.fps


# arrays inside: equality is identity (numpy's == is elementwise), so it stays hashable
@dataclass(frozen=True, eq=False)
class F0Track(Track):
    """F0 on the frame grid, with NaN where the frame is unvoiced.

    Parameters
    ----------
    voiced : bool array of shape (n_frames,)
        True where the pitch tracker found a voiced frame; ``values`` is NaN exactly where this is False.
    """

    voiced: np.ndarray

    def __post_init__(self) -> None:
        super().__post_init__()
        voiced = _frozen_array(self.voiced, dtype=bool, name="voiced mask")
        if voiced.shape != self.values.shape:
            raise ParameterError(
                f"voiced mask has {voiced.shape[0]} frames but the F0 track has {self.values.shape[0]}"
            )
        if np.any(np.isnan(self.values) == voiced):
            raise ParameterError("F0 values must be NaN exactly where the voiced mask is False")
        object.__setattr__(self, "voiced", voiced)
