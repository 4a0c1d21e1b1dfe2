"""Descriptions of a .fap file: the JSON of ``prosody inspect --json`` and a short human summary."""

from __future__ import annotations

import numpy as np

from .fapfile import FapFile
from .table import BY_NUMBER, RADIANS_PER_AU


def _plain(value: float) -> int | float:
    return int(value) if float(value).is_integer() else float(value)


def inspect_json(fap: FapFile) -> dict:
    """``{"version", "name", "fps", "frames", "faps": {"<n>": [value or None per frame]}}``.

    Every FAP whose mask bit is set in at least one frame is listed, with None where it is masked off.
    """
    stream = fap.stream
    faps = {}
    for number in stream.active_faps:
        column = number - 1
        faps[str(number)] = [
            _plain(value) if active else None
            for value, active in zip(stream.values[:, column].tolist(), stream.mask[:, column].tolist(), strict=False)
        ]
    return {"version": fap.version, "name": stream.name, "fps": _plain(stream.fps), "frames": stream.n_frames,
            "faps": faps}


def inspect_summary(fap: FapFile) -> str:
    """A few lines for a person: duration, active FAPs by name, and their ranges: head and eye angles in
    degrees, the rest in their FAP units (ENS, MNS, MW, IRISD, ES: 1/1024 of the face's reference distance),
    the units everything else in the project speaks."""
    stream = fap.stream
    lines = [
        f"{fap.path}: MPEG-4 FAP {fap.version or '(no header)'}, name {stream.name!r}",
        f"  {stream.n_frames} frames at {stream.fps:g} fps = {stream.duration_s:.2f} s",
        f"  {len(stream.active_faps)} active FAPs",
    ]
    for number in stream.active_faps:
        info = BY_NUMBER[number]
        active = stream.values[stream.mask[:, number - 1], number - 1]
        share = active.size / max(1, stream.n_frames)
        if info.fapu == "AU":
            low, high = np.degrees(active.min() * RADIANS_PER_AU), np.degrees(active.max() * RADIANS_PER_AU)
            unit = "deg"
        else:
            low, high, unit = active.min(), active.max(), info.fapu
        lines.append(f"  {number:>2} {info.name:<24} {low:+10.4g} .. {high:+10.4g} {unit:<6} "
                     f"(active in {share:.0%} of frames)")
    return "\n".join(lines)
