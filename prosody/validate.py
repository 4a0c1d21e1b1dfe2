"""Checks of the values callers give, once for the whole package (in the manner of librosa's ``valid_*``).

Each ``valid_*`` function returns the value in its plain type when it is acceptable and raises
:class:`~prosody.errors.ConfigError` naming the parameter otherwise, so that every module says the same thing
about the same mistake.

Examples
--------
>>> valid_seed(3)
3
>>> valid_seed(-1)
Traceback (most recent call last):
...
prosody.errors.ConfigError: seed must be a whole number >= 0, got -1
>>> valid_number(0.5, "pitch_share", 0.0, 1.0)
0.5
"""

from __future__ import annotations

import math
import numbers

from .errors import ConfigError

#: The most seeds a measure is averaged over.
MAX_SEEDS = 1000


def is_number(value: object) -> bool:
    """A real, finite number (an int or float, numpy's too), not a bool."""
    return (isinstance(value, numbers.Real) and not isinstance(value, bool)
            and math.isfinite(float(value)))


def valid_whole(value: object, name: str, low: int, high: int | None = None) -> int:
    """A whole number (an int, numpy's too, not a bool) from ``low`` to ``high`` (no upper end when None).

    Parameters
    ----------
    value : object
        The value given.
    name : str
        How the message names it.
    low, high : int
        The range, both ends included.

    Returns
    -------
    int
    """
    if not (isinstance(value, numbers.Integral) and not isinstance(value, bool)
            and low <= int(value) and (high is None or int(value) <= high)):
        shown = f">= {low}" if high is None else f"from {low} to {high}"
        raise ConfigError(f"{name} must be a whole number {shown}, got {value!r}", parameter=name)
    return int(value)


def valid_seed(seed: object, name: str = "seed") -> int:
    """A random seed: :func:`valid_whole` from 0, with no upper end."""
    return valid_whole(seed, name, 0)


def valid_seeds(seeds: object, name: str = "seeds") -> int:
    """A number of seeds to average over: :func:`valid_whole` from 1 to :data:`MAX_SEEDS`."""
    return valid_whole(seeds, name, 1, MAX_SEEDS)


def valid_number(value: object, name: str, low: float, high: float) -> float:
    """A finite number in ``[low, high]``.

    Parameters
    ----------
    value : object
        The value given.
    name : str
        How the message names it.
    low, high : float
        The range, both ends included.

    Returns
    -------
    float
    """
    if not (is_number(value) and low <= float(value) <= high):  # type: ignore[arg-type]
        raise ConfigError(f"{name} must be a number in [{low:g}, {high:g}], got {value!r}", parameter=name)
    return float(value)  # type: ignore[arg-type]
