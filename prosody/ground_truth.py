"""Recorded motion as a FAP stream: the GROUND_TRUTH condition.

Two sources are read: a .fap file, and the ``<clip>.head.csv`` convention of SPEC section 9 (columns
frame, time_s, rx_rad, ry_rad, rz_rad at 30 fps; FAP 48 = rx, 49 = ry, 50 = rz, times 1e5 for AU, each
clip's median pose removed since FAPs are displacements from a neutral pose).
"""

from __future__ import annotations

import csv
import os
from pathlib import Path

import numpy as np

from .errors import GroundTruthError
from .fap_table import HEAD_FAPS, PROSODY_FAPS, RADIANS_PER_AU
from .stream import FapStream

#: Frame rate of the head.csv convention.
HEAD_CSV_FPS = 30.0
HEAD_CSV_COLUMNS = ("frame", "time_s", "rx_rad", "ry_rad", "rz_rad")
#: Largest length difference (frames) between audio and recorded motion that is trimmed or padded.
MAX_LENGTH_MISMATCH_FRAMES = 2


def read_head_csv(path: str | os.PathLike[str], *, remove_median: bool = True) -> FapStream:
    """Read a ``<clip>.head.csv`` into a stream with FAP 48-50 in AU.

    Raises
    ------
    GroundTruthError
        Missing file, wrong columns, non-numeric or non-finite values, or frames that are not 0, 1, 2, ...
    """
    name = str(path)
    try:
        with open(path, newline="", encoding="utf-8") as handle:
            rows = list(csv.reader(handle))
    except FileNotFoundError:
        raise GroundTruthError(f"{name}: no such file") from None
    except (OSError, UnicodeDecodeError) as error:
        raise GroundTruthError(f"{name}: cannot be read as CSV ({error})") from None
    if not rows or tuple(cell.strip() for cell in rows[0]) != HEAD_CSV_COLUMNS:
        found = ",".join(rows[0]) if rows else "nothing"
        raise GroundTruthError(f"{name}, line 1: expected the header {','.join(HEAD_CSV_COLUMNS)}, found {found!r}")
    data = np.empty((len(rows) - 1, 5))
    for index, row in enumerate(rows[1:]):
        try:
            if len(row) != 5:
                raise ValueError(f"{len(row)} columns")
            data[index] = [float(cell) for cell in row]
        except ValueError as error:
            raise GroundTruthError(f"{name}, line {index + 2}: expected 5 numbers, found {row!r} ({error})") from None
    if data.shape[0] == 0:
        raise GroundTruthError(f"{name}: no frames")
    if not np.all(np.isfinite(data)):
        line = int(np.argmin(np.all(np.isfinite(data), axis=1))) + 2
        raise GroundTruthError(f"{name}, line {line}: values must be finite")
    if not np.array_equal(data[:, 0], np.arange(data.shape[0])):
        line = int(np.argmax(data[:, 0] != np.arange(data.shape[0]))) + 2
        raise GroundTruthError(f"{name}, line {line}: frames must be numbered 0, 1, 2, ... in order")
    angles = data[:, 2:5]
    if remove_median:
        angles = angles - np.median(angles, axis=0)  # resting pose out: SPEC section 9
    curves = {fap: angles[:, axis] / RADIANS_PER_AU for axis, fap in enumerate(HEAD_FAPS)}
    return FapStream.from_curves(curves, fps=HEAD_CSV_FPS, name=Path(name).name.removesuffix(".head.csv"))


def read_motion(path: str | os.PathLike[str]) -> FapStream:
    """Recorded prosody motion from a ``.head.csv`` or a ``.fap`` file (other FAPs dropped)."""
    from .fapfile import read_fap

    name = str(path)
    if name.endswith(".csv"):
        return read_head_csv(path)
    if name.lower().endswith(".fap"):
        return read_fap(path).stream.select(PROSODY_FAPS)
    raise GroundTruthError(f"{name}: ground truth must be a .head.csv or a .fap file")


def fit_to_grid(motion: FapStream, *, n_frames: int, fps: float, source: str,
                max_mismatch_frames: int = MAX_LENGTH_MISMATCH_FRAMES) -> FapStream:
    """Put recorded motion on the audio's grid: resample if the rate differs, then trim or hold the last
    frame to ``n_frames``, refusing a length difference above ``max_mismatch_frames``."""
    if motion.fps != fps:
        motion = motion.resampled(fps)
    difference = motion.n_frames - n_frames
    if abs(difference) > max_mismatch_frames:
        raise GroundTruthError(
            f"{source}: recorded motion has {motion.n_frames} frames ({motion.duration_s:.2f} s) but the audio "
            f"has {n_frames} ({n_frames / fps:.2f} s); they differ by more than {max_mismatch_frames} frames"
        )
    if difference >= 0:
        return FapStream(motion.values[:n_frames], motion.mask[:n_frames], fps, motion.name)
    pad = -difference
    last_values = np.repeat(motion.values[-1:], pad, axis=0)
    last_mask = np.repeat(motion.mask[-1:], pad, axis=0)
    return FapStream(np.vstack([motion.values, last_values]), np.vstack([motion.mask, last_mask]), fps,
                     motion.name)
