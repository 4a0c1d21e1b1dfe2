"""A human head: the angles a neck can reach and the height a brow can rise, kept whatever the controls ask.

Gains and expressivity controls multiply motion; at their extremes they would turn a head 170 degrees or
more. Every generated stream is brought within these limits last, after the gains:

- the head (FAP 48-50, from upright): pitch 45 degrees, yaw 60 degrees, roll 45 degrees either way, the
  average active ranges of the adult cervical spine that the American Academy of Orthopaedic Surgeons
  publishes (flexion and extension 45, rotation 60, lateral bending 45 degrees);
- the brows (FAP 31-36): 400 units (ENS / 1024) up or down, about 0.4 of the eye-nose distance (some 12 mm on
  an adult face), more than the highest raise of surprise.

The limit is soft: a value within 3/4 of its limit is kept exactly; beyond, it bends smoothly (its slope
continuous) towards the limit, reached only far beyond it, so a head that swings far slows down as a neck
does instead of stopping at a wall. Recorded motion (``--condition truth``, ``--base``) is never limited: it is what
a person did.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from ..fap.stream import FapStream
from ..fap.table import RADIANS_PER_AU

#: Largest angle from upright, per head FAP (degrees).
HEAD_LIMITS_DEG = {48: 45.0, 49: 60.0, 50: 45.0}
#: Largest brow raise or lowering (FAP units, ENS / 1024).
BROW_LIMIT = 400.0
#: Share of a limit below which values are kept exactly.
KNEE = 0.75
#: FAP -> its limit in FAP units.
LIMITS = {**{fap: math.radians(degrees) / RADIANS_PER_AU for fap, degrees in HEAD_LIMITS_DEG.items()},
          **dict.fromkeys(range(31, 37), BROW_LIMIT)}


class HumanLimitWarning(UserWarning):
    """Generated motion went past where a human head or brow can go and was bent back within it."""


def soft_limit(values: np.ndarray, limit: float) -> np.ndarray:
    """``values`` kept within ``[-limit, limit]``: unchanged up to ``KNEE * limit``, then a tanh bend whose slope
    is 1 at the knee.

    Examples
    --------
    >>> soft_limit(np.array([10.0, -74.0, 100.0, -1e9]), 100.0).round(2).tolist()
    [10.0, -74.0, 94.04, -100.0]
    """
    values = np.asarray(values, float)
    knee = KNEE * limit
    span = limit - knee
    magnitude = np.abs(values)
    bent = knee + span * np.tanh((magnitude - knee) / span)
    return np.where(magnitude > knee, np.sign(values) * bent, values)


def within_human_limits(stream: FapStream) -> tuple[FapStream, dict[int, float]]:
    """The stream with its head and brow FAPs within :data:`LIMITS`; and, per FAP that was bent, the share of
    its frames beyond the knee."""
    bent: dict[int, float] = {}
    values = None
    for fap, limit in LIMITS.items():
        column = stream.values[:, fap - 1]
        active = stream.mask[:, fap - 1]
        beyond = active & (np.abs(column) > KNEE * limit)
        if not beyond.any():
            continue
        if values is None:
            values = stream.values.copy()
        values[:, fap - 1] = np.where(active, soft_limit(column, limit), column)
        bent[fap] = float(beyond.sum() / max(int(active.sum()), 1))
    if values is None:
        return stream, bent
    return FapStream._adopt(values, stream.mask, stream.fps, stream.name), bent


def warn_if_bent(bent: dict[int, float], *, stacklevel: int = 2) -> None:
    """One warning naming what was bent back, and how often."""
    if not bent:
        return
    names = {48: "pitch", 49: "yaw", 50: "roll"}
    parts = []
    for fap, share in sorted(bent.items()):
        what = f"{names[fap]} (±{HEAD_LIMITS_DEG[fap]:g}°)" if fap in names else f"FAP {fap} (±{BROW_LIMIT:g})"
        parts.append(f"{what} on {max(share, 0.001):.1%} of frames")
    warnings.warn("the motion went past what a human head or brow can do and was bent back within it: "
                  + ", ".join(parts) + "; lower the gains or --spatial", HumanLimitWarning, stacklevel=stacklevel + 1)


def limit_frame(faps: dict[int, float]) -> dict[int, float]:
    """One live frame's values within :data:`LIMITS` (the same bend as :func:`within_human_limits`)."""
    out = dict(faps)
    for fap, value in faps.items():
        limit = LIMITS.get(fap)
        if limit is not None and math.isfinite(value) and abs(value) > KNEE * limit:
            out[fap] = float(soft_limit(np.array([value]), limit)[0])
    return out
