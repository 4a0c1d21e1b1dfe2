"""Recorded motion's files, beside the FAP formats: what ``prosody track`` writes and the GROUND_TRUTH
condition reads.

Read as a FAP stream: a .fap file, and the ``<clip>.head.csv`` convention of docs/dependencies.md (columns
frame, time_s, rx_rad, ry_rad, rz_rad at 30 fps; FAP 48 = rx, 49 = ry, 50 = rz, times 1e5 for AU, each
clip's median pose removed since FAPs are displacements from a neutral pose); the video-tracked brows
(``<clip>.brows.csv``) as FAP 31-36 and mouth (``<clip>.mouth.csv``) as measures. The columns of the three
files are :data:`HEAD_COLUMNS`, :data:`BROWS_COLUMNS` and :data:`MOUTH_COLUMNS` (after ``frame`` and
``time_s``), one schema for the tracker that writes them and the readers.
"""

from __future__ import annotations

import csv
import math
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from audio_features.inputs import open_input, reading

from ..errors import GroundTruthError
from .stream import FapStream
from .table import HEAD_FAPS, PROSODY_FAPS, RADIANS_PER_AU

#: Frame rate of the head.csv convention.
HEAD_CSV_FPS = 30.0
HEAD_CSV_COLUMNS = ("frame", "time_s", "rx_rad", "ry_rad", "rz_rad")
#: MediaPipe's mouth blendshapes that the tracker keeps, in the mouth file's order.
MOUTH_BLENDSHAPES = ("jawOpen", "mouthClose", "mouthFunnel", "mouthPucker", "mouthSmileLeft", "mouthSmileRight",
                     "mouthStretchLeft", "mouthStretchRight", "mouthPressLeft", "mouthPressRight", "mouthRollLower",
                     "mouthRollUpper", "mouthLowerDownLeft", "mouthLowerDownRight", "mouthUpperUpLeft",
                     "mouthUpperUpRight")


def snake_case(name: str) -> str:
    """``mouthSmileLeft`` -> ``mouth_smile_left``."""
    return "".join("_" + c.lower() if c.isupper() else c for c in name)


#: Columns after frame and time_s of the tracker's head, brows and mouth files (the talking-heads order).
HEAD_COLUMNS = HEAD_CSV_COLUMNS[2:]
BROWS_COLUMNS = ("brow_inner_up", "brow_outer_up_l", "brow_outer_up_r", "inner_height_l", "inner_height_r",
                 "outer_height_l", "outer_height_r")
MOUTH_COLUMNS = tuple(snake_case(name) for name in MOUTH_BLENDSHAPES) + ("lip_opening", "mouth_width", "nose_chin")
ALL_COLUMNS = HEAD_COLUMNS + BROWS_COLUMNS + MOUTH_COLUMNS
#: How far a head.csv row's time_s may stray from frame / 30 (its rounding to a few decimals).
TIME_TOLERANCE_S = 0.002
#: Largest length difference (frames) between audio and recorded motion that is trimmed or padded.
MAX_LENGTH_MISMATCH_FRAMES = 2
#: Largest recorded-motion CSV read (64 MiB: about ten hours of head.csv rows at 30 fps).
MAX_CSV_BYTES = 64 << 20


def _csv_rows(path: str | os.PathLike[str], name: str) -> list[list[str]]:
    """All rows of a CSV file; unreadable files and malformed rows (a cell over the csv module's size limit)
    are a GroundTruthError naming the file and line."""
    try:
        # utf-8-sig: a byte-order mark (spreadsheets write one) is not part of the first column's name
        with reading(name, GroundTruthError, wanted="CSV file"), open_input(
                path, text=True, newline="", encoding="utf-8-sig", max_bytes=MAX_CSV_BYTES) as handle:
            reader = csv.reader(handle)
            try:
                return list(reader)
            except csv.Error as error:
                raise GroundTruthError(f"{name}, line {reader.line_num}: not a CSV row ({error})") from None
    except UnicodeDecodeError as error:
        raise GroundTruthError(f"{name}: cannot be read as CSV ({error})") from None


#: Longest stretch of empty head cells (a tracker's frames without a face) bridged by interpolation and
#: measured, in s; longer stretches are bridged too (so the stream stays continuous) but left out of the
#: measures (their frames are masked).
MAX_MEASURED_GAP_S = 0.5


class RecordedGapWarning(UserWarning):
    """Recorded motion has long stretches without a face; they are left out of the measures."""


def _bridge_gaps(angles: np.ndarray, *, fps: float, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Empty (NaN) rows filled by linear interpolation (the edges held); returns the filled angles and the
    rows that count in the measures (False inside gaps longer than :data:`MAX_MEASURED_GAP_S`)."""
    known = np.all(np.isfinite(angles), axis=1)
    measured = np.ones(angles.shape[0], bool)
    if known.all():
        return angles, measured
    frames = np.arange(angles.shape[0])
    filled = np.column_stack([np.interp(frames, frames[known], angles[known, axis]) for axis in range(3)])
    longest = int(round(MAX_MEASURED_GAP_S * fps))
    padded = np.concatenate([[False], ~known, [False]])
    starts = np.flatnonzero(padded[1:] & ~padded[:-1])
    ends = np.flatnonzero(~padded[1:] & padded[:-1])
    long_gaps = [(a, b) for a, b in zip(starts, ends, strict=True) if b - a > longest]
    for a, b in long_gaps:
        measured[a:b] = False
    if long_gaps:
        left_out = sum(b - a for a, b in long_gaps)
        warnings.warn(RecordedGapWarning(
            f"{name}: {len(long_gaps)} stretch(es) without a face longer than {MAX_MEASURED_GAP_S:g} s "
            f"({left_out / fps:.2f} s in all, from {starts[0] / fps:.2f} s) are bridged but left out of the "
            "measures"), stacklevel=3)
    return filled, measured


def _head_csv_numbers(path: str | os.PathLike[str], name: str) -> np.ndarray:
    """The rows of a head.csv as numbers (frame, time_s, rx, ry, rz; empty angle cells NaN), its header checked."""
    rows = _csv_rows(path, name)
    if not rows or tuple(cell.strip() for cell in rows[0]) != HEAD_CSV_COLUMNS:
        found = ",".join(rows[0]) if rows else "nothing"
        raise GroundTruthError(f"{name}, line 1: expected the header {','.join(HEAD_CSV_COLUMNS)}, found {found!r}")
    data = np.empty((len(rows) - 1, 5))
    for index, row in enumerate(rows[1:]):
        try:
            if len(row) != 5:
                raise ValueError(f"{len(row)} columns")
            cells = [cell.strip() for cell in row]
            if not cells[0] or not cells[1]:
                raise ValueError("frame and time_s must be given")
            if any(not cell for cell in cells[2:]) and any(cells[2:]):
                raise ValueError("the three angles are given together or left empty together")
            data[index] = [float(cell) if cell else math.nan for cell in cells]
        except ValueError as error:
            raise GroundTruthError(f"{name}, line {index + 2}: expected 5 numbers (or frame, time_s and three "
                                   f"empty cells), found {row!r} ({error})") from None
    return data


def _check_head_csv(data: np.ndarray, name: str) -> None:
    """Refuse a head.csv without frames or faces, with values not finite or beyond a head's turn, or off the
    30 fps grid; the message names the line."""
    if data.shape[0] == 0:
        raise GroundTruthError(f"{name}: no frames")
    empty = np.asarray(np.isnan(data[:, 2:]).all(axis=1), dtype=bool)
    if empty.all():
        raise GroundTruthError(f"{name}: no frame with a face (every angle cell is empty)")
    finite = np.isfinite(data) | np.column_stack([np.zeros((data.shape[0], 2), bool), np.repeat(empty[:, None], 3, 1)])
    if not finite.all():
        line = int(np.argmin(finite.all(axis=1))) + 2
        raise GroundTruthError(f"{name}, line {line}: values must be finite")
    beyond = np.abs(np.nan_to_num(data[:, 2:])) > math.pi
    if beyond.any():
        line = int(np.argmax(beyond.any(axis=1))) + 2
        raise GroundTruthError(f"{name}, line {line}: a head angle beyond pi rad (180 degrees) is not a head's "
                               "rotation; angles are in radians")
    if not np.array_equal(data[:, 0], np.arange(data.shape[0])):
        line = int(np.argmax(data[:, 0] != np.arange(data.shape[0]))) + 2
        raise GroundTruthError(f"{name}, line {line}: frames must be numbered 0, 1, 2, ... in order")
    off_grid = np.abs(data[:, 1] - data[:, 0] / HEAD_CSV_FPS) > TIME_TOLERANCE_S  # rounding, not re-timing
    if off_grid.any():
        line = int(np.argmax(off_grid)) + 2
        raise GroundTruthError(
            f"{name}, line {line}: time_s {float(data[line - 2, 1])!r} is not frame {int(data[line - 2, 0])} at "
            f"{HEAD_CSV_FPS:g} fps ({data[line - 2, 0] / HEAD_CSV_FPS:.4f} s): a head.csv is 30 fps, frame k at k/30 s"
        )


def read_head_csv(path: str | os.PathLike[str], *, remove_median: bool = True) -> FapStream:
    """Read a ``<clip>.head.csv`` into a stream with FAP 48-50 in AU.

    Empty cells (a face tracker's frames without a face) are bridged by linear interpolation; stretches
    longer than :data:`MAX_MEASURED_GAP_S` are bridged too but masked (``stream.mask`` False for FAP 48-50),
    which the measures leave out, with a :class:`RecordedGapWarning`.

    Raises
    ------
    GroundTruthError
        Missing file, wrong columns, non-numeric or non-finite values, no frame with a face, or frames that
        are not 0, 1, 2, ...
    """
    name = str(path)
    data = _head_csv_numbers(path, name)
    _check_head_csv(data, name)
    angles, measured = _bridge_gaps(data[:, 2:5], fps=HEAD_CSV_FPS, name=name)
    if remove_median:
        angles = angles - np.median(angles[measured], axis=0)  # resting pose out: docs/dependencies.md
    curves = {fap: angles[:, axis] / RADIANS_PER_AU for axis, fap in enumerate(HEAD_FAPS)}
    stream = FapStream.from_curves(curves, fps=HEAD_CSV_FPS, name=Path(name).name.removesuffix(".head.csv"))
    if not measured.all():
        mask = stream.mask.copy()
        for fap in HEAD_FAPS:
            mask[:, fap - 1] = measured
        stream = FapStream(stream.values, mask, stream.fps, stream.name)
    return stream


#: Columns of the ``<clip>.brows.csv`` convention used as recorded brows.
BROWS_CSV_HEIGHTS = ("inner_height_l", "inner_height_r", "outer_height_l", "outer_height_r")
#: ENS units per unit of the brows.csv heights (brow-to-eye-corner distance over the outer eye-corner
#: distance): the eye-nose separation ENS0 is about half the outer eye-corner distance in adults (about 4.5
#: and 9 cm), so one eye-corner distance is about 2 ENS0 = 2048 ENS units.
ENS_PER_EYE_WIDTH = 2048.0


def _tracked_columns(path: str | os.PathLike[str], columns: tuple[str, ...],
                     optional: tuple[str, ...] = ()) -> np.ndarray:
    """The named columns of a video-tracked CSV (frames 0, 1, 2, ...), NaN where the cell is empty (no face),
    then the ``optional`` ones (all NaN where the file has no such column)."""
    name = str(path)
    rows = _csv_rows(path, name)
    header = [cell.strip() for cell in rows[0]] if rows else []
    missing = [column for column in ("frame", *columns) if column not in header]
    if missing:
        raise GroundTruthError(f"{name}, line 1: missing column(s) {', '.join(missing)}")
    frame = header.index("frame")
    present = [(position, header.index(key)) for position, key in enumerate((*columns, *optional)) if key in header]
    data = np.full((len(rows) - 1, len(columns) + len(optional)), np.nan)
    for line, row in enumerate(rows[1:], start=2):
        try:
            if len(row) != len(header):
                raise ValueError(f"{len(row)} columns, expected {len(header)}")
            if float(row[frame]) != line - 2:
                raise GroundTruthError(f"{name}, line {line}: frames must be numbered 0, 1, 2, ... in order")
            for position, column in present:
                cell = row[column].strip()
                if cell:
                    data[line - 2, position] = float(cell)
        except ValueError as error:
            raise GroundTruthError(f"{name}, line {line}: expected numbers or empty cells ({error})") from None
    if not np.all(np.isfinite(data) | np.isnan(data)):
        raise GroundTruthError(f"{name}: values must be finite numbers or empty cells")
    if data.shape[0] == 0 or not np.isfinite(data[:, :len(columns)]).any(axis=1).any():
        raise GroundTruthError(f"{name}: no frame with a tracked face")
    return data


#: Columns of ``<clip>.mouth.csv`` that the mouth measures read.
MOUTH_CSV_COLUMNS = ("lip_opening", "mouth_funnel", "mouth_pucker", "mouth_width")


@dataclass(frozen=True, eq=False)
class RecordedMouth:
    """A video-tracked mouth at 30 fps: NaN where no face was found.

    ``lip_opening`` and ``mouth_width`` are in outer-eye-corner widths; ``rounding`` is the blendshape
    weights ``mouth_funnel + mouth_pucker``; ``jaw_open`` is the tracker's own ``jawOpen`` blendshape weight (a
    second measure of the same opening, see :func:`prosody.measures.opening_agreement`), or None where the file
    has no such column.
    """

    lip_opening: np.ndarray
    rounding: np.ndarray
    mouth_width: np.ndarray
    fps: float = HEAD_CSV_FPS
    jaw_open: np.ndarray | None = None

    @property
    def n_frames(self) -> int:
        return self.lip_opening.size


def read_mouth_csv(path: str | os.PathLike[str]) -> RecordedMouth:
    """Read a ``<clip>.mouth.csv`` (columns as the talking-heads data define them; others ignored).

    Raises
    ------
    GroundTruthError
        Missing file or columns, frames not numbered 0, 1, 2, ..., non-numeric cells, or no face at all.
    """
    opening, funnel, pucker, width, jaw = _tracked_columns(path, MOUTH_CSV_COLUMNS, optional=("jaw_open",)).T
    return RecordedMouth(opening, funnel + pucker, width, jaw_open=jaw if np.isfinite(jaw).any() else None)


def mouth_beside(path: str | os.PathLike[str]) -> Path | None:
    """The ``<clip>.mouth.csv`` beside a ``<clip>.head.csv`` (or any ``<clip>.<ending>``), if there is one."""
    name = str(path)
    for ending in (".head.csv", ".brows.csv", ".fap", ".wav"):
        if name.endswith(ending):
            candidate = Path(name.removesuffix(ending) + ".mouth.csv")
            return candidate if candidate.is_file() else None
    return None


def read_brows_csv(path: str | os.PathLike[str]) -> FapStream:
    """Read a ``<clip>.brows.csv`` (video-tracked brow heights) as FAP 31-34 in ENS units.

    FAP 31 / 32 (inner brow, the speaker's own left / right) are ``inner_height_l`` / ``_r``; FAP 33 / 34
    (middle) the mean of the inner and outer height of that side. Each is taken relative to its median
    (the resting brow) and scaled by :data:`ENS_PER_EYE_WIDTH`. Frames where the face was not found (empty
    cells) are filled by linear interpolation between their neighbours.

    Raises
    ------
    GroundTruthError
        Missing file or columns, frames not numbered 0, 1, 2, ..., non-numeric cells, or no face found at all.
    """
    name = str(path)
    data = _tracked_columns(path, BROWS_CSV_HEIGHTS)
    frames = np.arange(data.shape[0])
    for column in range(data.shape[1]):
        known = np.isfinite(data[:, column])
        if not known.any():
            raise GroundTruthError(f"{name}: column {BROWS_CSV_HEIGHTS[column]} is empty")
        data[:, column] = np.interp(frames, frames[known], data[known, column])
    heights = (data - np.median(data, axis=0)) * ENS_PER_EYE_WIDTH
    inner_l, inner_r, outer_l, outer_r = heights.T
    curves = {31: inner_l, 32: inner_r, 33: (inner_l + outer_l) / 2, 34: (inner_r + outer_r) / 2}
    return FapStream.from_curves(curves, fps=HEAD_CSV_FPS, name=Path(name).name.removesuffix(".brows.csv"))


def brows_beside(path: str | os.PathLike[str]) -> Path | None:
    """The ``<clip>.brows.csv`` beside a ``<clip>.head.csv``, if there is one."""
    name = str(path)
    if not name.endswith(".head.csv"):
        return None
    candidate = Path(name.removesuffix(".head.csv") + ".brows.csv")
    return candidate if candidate.is_file() else None


def read_motion(path: str | os.PathLike[str]) -> FapStream:
    """Recorded prosody motion from a ``.head.csv`` (with the ``.brows.csv`` beside it, if any) or a
    ``.fap`` file (other FAPs dropped)."""
    from ..fap.fapfile import read_fap

    name = str(path)
    if name.endswith(".csv"):
        head = read_head_csv(path)
        brows = brows_beside(path)
        if brows is None:
            return head
        recorded = read_brows_csv(brows)
        if abs(recorded.n_frames - head.n_frames) > MAX_LENGTH_MISMATCH_FRAMES:
            raise GroundTruthError(f"{brows}: {recorded.n_frames} frames, but {name} has {head.n_frames}")
        recorded = fit_to_grid(recorded, n_frames=head.n_frames, fps=head.fps, source=str(brows))
        return head.merged_over(recorded)
    if name.lower().endswith(".fap"):
        return read_fap(path).stream.select(PROSODY_FAPS)
    raise GroundTruthError(f"{name}: ground truth must be a .head.csv or a .fap file")


def fit_to_grid(motion: FapStream, *, n_frames: int, fps: float, source: str,
                max_mismatch_frames: int = MAX_LENGTH_MISMATCH_FRAMES) -> FapStream:
    """Put recorded motion on the audio's grid: resample if the rate differs, then trim or hold the last
    frame to ``n_frames``, refusing a length difference above ``max_mismatch_frames``."""
    # lengths are compared before resampling: a stream at a tiny frame rate must not be blown up first
    tolerance_s = (max_mismatch_frames + 1) / fps + 1.0 / motion.fps
    if abs(motion.duration_s - n_frames / fps) > tolerance_s:
        raise GroundTruthError(
            f"{source}: recorded motion lasts {motion.duration_s:.2f} s ({motion.n_frames} frames at "
            f"{motion.fps:g} fps) but the audio lasts {n_frames / fps:.2f} s; they differ by more than "
            f"{max_mismatch_frames} frames"
        )
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
