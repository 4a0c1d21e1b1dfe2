"""Reading and writing MPEG-4 FAP files (.fap), docs/fap.md.

Writing produces the subset that Xface, the Java Greta and the older C++ Greta all read: header
``2.1 <name> <integer fps> <N>``, 68 mask tokens, frames 0..N-1, integer values, FAP 1 and 2 masked off,
no comments, every mask and value line ending in a space and a newline (as Greta's own writer: the C++
Greta's buffer reader needs the space), and no blank line at the end.

Reading is liberal (versions 2.0/2.1, names with spaces or paths, CRLF, tabs, trailing spaces, ``#``
comment lines, 69-token masks, frame numbers from 1, float values, masks that change, header counts that
disagree, no header at all) and reports every irregularity in :attr:`FapFile.warnings`. Malformed input
raises :class:`FapFormatError` naming the file, the line and what was expected.
"""

from __future__ import annotations

import math
import os
import re
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from audio_features.atomic import atomic_write
from audio_features.inputs import open_input

from ..errors import FapFormatError, FapIrregularityWarning, FapWriteError
from .stream import FapStream
from .table import N_FAPS

#: Frame rate assumed for a stream with no header (MPEG-4 FAP streams are most often 25 fps).
DEFAULT_HEADERLESS_FPS = 25.0
#: Longest line read: a mask is 137 bytes and a full value line well under 2 kB; a longer line is not a .fap.
MAX_LINE_BYTES = 1 << 16
#: Largest .fap file read (two hours of every FAP at 30 fps is under 100 MB).
MAX_FAP_BYTES = 1 << 30
#: Frame rates a .fap header may state; outside them a stream describes nothing a face can play.
FPS_RANGE = (1.0, 1000.0)
#: Values that FAP 1 (viseme) and FAP 2 (expression) take in their full MPEG-4 form.
_HIGH_LEVEL_WIDTHS = {1: 4, 2: 6}
_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")


# arrays inside: equality is identity (numpy's == is elementwise), so it stays hashable
@dataclass(frozen=True, eq=False)
class FapFile:
    """A .fap file as read: the stream plus what the file said about itself.

    Attributes
    ----------
    stream : FapStream
    version : str or None
        Version token of the header (``"2.0"``, ``"2.1"``), None for a headerless stream.
    header_frames : int or None
        Frame count the header promised (None without header).
    first_frame_number : int or None
        Frame number written on the first value line.
    integer_values : bool
        True when every value token was an integer.
    warnings : tuple of str
        Irregularities found and how they were handled.
    """

    stream: FapStream
    path: str
    version: str | None
    header_frames: int | None
    first_frame_number: int | None
    integer_values: bool
    warnings: tuple[str, ...] = field(default=())


def _is_mask_line(tokens: list[str]) -> bool:
    return len(tokens) in (N_FAPS, N_FAPS + 1) and all(token in ("0", "1") for token in tokens)


def _parse_number(token: str, *, path: str, line: int, what: str) -> float:
    if not _NUMBER.match(token):
        raise FapFormatError(path, line, f"expected {what}, found {token!r}")
    value = float(token)
    if not math.isfinite(value):
        raise FapFormatError(path, line, f"{what} {token!r} is out of range")
    return value


def _read_lines(path: str | os.PathLike[str], name: str) -> Iterator[str]:
    """The file's lines one at a time, decoded as Latin-1, each and all within bounds (a device or a huge line
    is refused)."""
    total = 0
    first = True
    try:
        with open_input(path, max_bytes=MAX_FAP_BYTES) as handle:
            while True:
                raw = handle.readline(MAX_LINE_BYTES + 1)
                if not raw:
                    break
                total += len(raw)
                if len(raw) > MAX_LINE_BYTES and not raw.endswith(b"\n"):
                    raise FapFormatError(name, None, f"a line longer than {MAX_LINE_BYTES} bytes: not a .fap file")
                if total > MAX_FAP_BYTES:
                    raise FapFormatError(name, None, f"larger than {MAX_FAP_BYTES >> 20} MiB: not a .fap file")
                if first and raw.startswith(b"\xef\xbb\xbf"):
                    raw = raw[3:]  # a UTF-8 byte-order mark, as some editors write: not part of the header
                first = False
                # a lone CR or another Unicode line break ends a line too, as it would in an editor
                yield from raw.decode("latin-1").splitlines()
    except FileNotFoundError:
        raise FapFormatError(name, None, "no such file") from None
    except IsADirectoryError:
        raise FapFormatError(name, None, "is a directory, not a .fap file") from None
    except OSError as error:
        raise FapFormatError(name, None, f"cannot be read ({error.strerror})") from None


def _content_lines(path: str | os.PathLike[str], name: str, notes: list[str]) -> Iterator[tuple[int, str]]:
    """(line number, stripped text) of every line that is neither blank nor a ``#`` comment."""
    commented = False
    for number, line in enumerate(_read_lines(path, name), start=1):
        if number <= 2 and "\0" in line:
            raise FapFormatError(name, 1, "holds binary data: not a .fap file (a text file of FAP values)")
        text = line.strip()
        if text.startswith("#"):
            commented = True
        elif text:
            yield number, text
    if commented:
        notes.append("comment lines ('#') skipped")


#: A value line of well-formed numbers, checked at once; token by token only when the line fails (to name
#: the token).
_NUMBER_PATTERN = r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?"
_NUMBERS_LINE = re.compile(rf"{_NUMBER_PATTERN}(?:\s+{_NUMBER_PATTERN})*")
#: What is left of a line of integers once digits, signs and blanks are deleted: nothing.
_INTEGER_CHARACTERS = str.maketrans("", "", "0123456789+- \t\f\v")
#: Frames gathered per block while reading, and distinct mask lines remembered.
_BLOCK_FRAMES = 4096
_MASK_CACHE = 256


@dataclass(frozen=True)
class _Mask:
    bits: np.ndarray  # N_FAPS or N_FAPS + 1 booleans
    expected: int  # values the mask sets
    extra: dict[int, int]  # FAP -> extra values of its multi-value form


def _read_mask(text: str, number: int, name: str, cache: dict[str, _Mask]) -> _Mask:
    mask = cache.get(text)
    if mask is None:
        tokens = text.split()
        if not _is_mask_line(tokens):
            raise FapFormatError(
                name, number, f"expected a mask line of {N_FAPS} tokens 0/1, found {len(tokens)} tokens "
                f"starting {' '.join(tokens[:4])!r}"
            )
        bits = np.array([token == "1" for token in tokens])
        extra = {fap: width - 1 for fap, width in _HIGH_LEVEL_WIDTHS.items() if bits[fap - 1]}
        mask = _Mask(bits, int(bits.sum()), extra)
        if len(cache) >= _MASK_CACHE:
            cache.clear()
        cache[text] = mask
    return mask


class _Frames:
    """Masks and values gathered in blocks of preallocated arrays, so a long file costs its arrays only."""

    def __init__(self) -> None:
        self.blocks: list[tuple[np.ndarray, np.ndarray]] = []
        self.count = 0

    def append(self, bits: np.ndarray, numbers: list[float]) -> None:
        slot = self.count % _BLOCK_FRAMES
        if slot == 0:
            self.blocks.append((np.zeros((_BLOCK_FRAMES, N_FAPS), dtype=bool), np.zeros((_BLOCK_FRAMES, N_FAPS))))
        masks, values = self.blocks[-1]
        row = np.zeros(bits.size)
        row[bits] = numbers
        masks[slot] = bits[:N_FAPS]
        values[slot] = row[:N_FAPS]
        self.count += 1

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        if not self.blocks:
            return np.zeros((0, N_FAPS)), np.zeros((0, N_FAPS), dtype=bool)
        values, masks = np.empty((self.count, N_FAPS)), np.empty((self.count, N_FAPS), dtype=bool)
        self.blocks.reverse()
        for start in range(0, self.count, _BLOCK_FRAMES):  # each block freed once copied: no second copy
            block_masks, block_values = self.blocks.pop()
            stop = min(start + _BLOCK_FRAMES, self.count)
            values[start:stop], masks[start:stop] = block_values[:stop - start], block_masks[:stop - start]
        return values, masks


def _value_numbers(tokens: list[str], text: str, number: int, name: str) -> tuple[list[float], bool]:
    """The FAP values of a value line (its tokens after the frame number) and whether all are integers."""
    values = tokens[1:]
    if not values:
        return [], True
    # the common line, integers only: a token of digits and signs that float() takes is an integer
    if not text.translate(_INTEGER_CHARACTERS):
        try:
            numbers = list(map(float, values))
        except ValueError:
            pass
        else:
            if math.isfinite(max(numbers)) and math.isfinite(min(numbers)):
                return numbers, True
    if _NUMBERS_LINE.fullmatch(text):
        numbers = list(map(float, values))
        if math.isfinite(max(numbers)) and math.isfinite(min(numbers)):
            return numbers, all(re.fullmatch(r"[+-]?\d+", token) for token in values)
    numbers = [_parse_number(token, path=name, line=number, what="a FAP value") for token in values]
    return numbers, all(re.fullmatch(r"[+-]?\d+", token) for token in values)


def read_fap(path: str | os.PathLike[str], *, default_fps: float = DEFAULT_HEADERLESS_FPS,
             strict: bool = False) -> FapFile:
    """Read a .fap file.

    The file is read line by line into arrays, so its size costs only the frames it holds (about 600 bytes
    each).

    Parameters
    ----------
    path : path-like
        The file. Bytes are decoded as Latin-1, so any byte sequence reads.
    default_fps : float > 0
        Frame rate for a stream without a header.
    strict : bool
        False (default): each irregularity the file has (comments, 69-token masks, renumbered frames, a wrong
        header count, float values, ...) is read as described and issued as a
        :class:`~prosody.errors.FapIrregularityWarning`, and listed in :attr:`FapFile.warnings`. True: the
        first irregularity is a :class:`~prosody.errors.FapFormatError`.

    Returns
    -------
    FapFile

    Raises
    ------
    FapFormatError
        Missing file, unreadable header, a mask line that is not 68 (or 69) tokens of 0/1, a value line
        whose count disagrees with its mask, or a non-numeric token; with ``strict``, any irregularity.
    """
    name = str(path)
    notes: list[str] = []
    lines = _content_lines(path, name, notes)
    try:
        first_number, first_line = next(lines)
    except StopIteration:
        raise FapFormatError(name, None, "the file holds no header, mask or value line") from None
    header = _read_header(first_number, first_line, name, default_fps, notes)
    pending = (first_number, first_line) if header.version is None else None  # a headerless stream's first mask
    reader = _FrameReader(name)
    while True:
        if pending is not None:
            (mask_number, mask_line), pending = pending, None
        else:
            following = next(lines, None)
            if following is None:
                break
            mask_number, mask_line = following
        value = next(lines, None)
        if value is None:
            raise FapFormatError(name, mask_number, "mask line without a value line: the file ends here")
        reader.read(mask_number, mask_line, *value)
    notes += reader.notes(header.frames)
    values, masks = reader.frames.arrays()
    stream = FapStream._adopt(values, masks, header.fps, header.name or Path(name).stem)  # made for it: not copied
    if strict and notes:
        raise FapFormatError(name, None, f"irregular .fap file (strict reading): {notes[0]}")
    for note in notes:
        warnings.warn(f"{name}: {note}", FapIrregularityWarning, stacklevel=2)
    return FapFile(stream, name, header.version, header.frames, reader.first_frame_number, reader.integer_values,
                   tuple(notes))


@dataclass(frozen=True)
class _Header:
    """A header line's reading: version, stream name, frame rate, promised frames (None where absent)."""

    version: str | None
    name: str | None
    fps: float
    frames: int | None


def _read_header(number: int, line: str, name: str, default_fps: float, notes: list[str]) -> _Header:
    """The header of a .fap file, or the defaults of a headerless stream (whose first line is a mask)."""
    tokens = line.split()
    if _is_mask_line(tokens):
        notes.append(f"no header line: a headerless stream, assumed {default_fps:g} fps")
        return _Header(None, None, default_fps, None)
    if len(tokens) < 3:
        raise FapFormatError(name, number, f"expected a header '<version> <name> <fps> <frames>', found {line!r}")
    version = tokens[0]
    _parse_number(version, path=name, line=number, what="a version number such as 2.1")
    fps = _parse_number(tokens[-2], path=name, line=number, what="the frame rate")
    count = _parse_number(tokens[-1], path=name, line=number, what="the number of frames")
    if fps <= 0 or count < 0 or count != int(count):
        raise FapFormatError(name, number, f"header frame rate {fps!r} or count {count!r} is invalid")
    if not FPS_RANGE[0] <= fps <= FPS_RANGE[1]:
        raise FapFormatError(name, number, f"header frame rate {fps:g} fps is outside "
                             f"{FPS_RANGE[0]:g}-{FPS_RANGE[1]:g} fps: no face plays it")
    # the name may hold spaces: it is whatever stands between the version and the last two tokens
    middle = re.match(r"^\S+\s+(.*?)\s*\S+\s+\S+$", line)
    if version not in ("2.0", "2.1"):
        notes.append(f"unknown version {version!r}: read as 2.1")
    return _Header(version, (middle.group(1) if middle else "") or None, fps, int(count))


class _FrameReader:
    """The frames of a .fap file, read pair by pair (mask line, value line), and what was irregular in them."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.frames = _Frames()
        self.mask_cache: dict[str, _Mask] = {}
        self.first_frame_number: int | None = None
        self.previous_frame_number: int | None = None
        self.consecutive = True
        self.integer_values = True
        self.wide_masks = 0
        self.high_level = 0

    def read(self, mask_number: int, mask_line: str, value_number: int, value_line: str) -> None:
        name = self.name
        mask = _read_mask(mask_line, mask_number, name, self.mask_cache)
        if mask.bits.size == N_FAPS + 1:
            self.wide_masks += 1
        value_tokens = value_line.split()
        if mask.extra and len(value_tokens) == mask.expected + 1 + sum(mask.extra.values()):
            # the full MPEG-4 forms of FAP 1 (viseme: 4 values) and FAP 2 (expression: 6 values) that Xface
            # and the C++ Greta read: the first value of each (the viseme / expression selected) is kept
            kept, position = [value_tokens[0]], 1
            for fap in (np.flatnonzero(mask.bits) + 1).tolist():
                kept.append(value_tokens[position])
                position += 1 + mask.extra.get(fap, 0)
            value_tokens = kept
            value_line = " ".join(kept)
            self.high_level += 1
        if len(value_tokens) != mask.expected + 1:
            raise FapFormatError(
                name, value_number, f"expected a frame number and {mask.expected} values (one per FAP set in the "
                f"mask on line {mask_number}), found {len(value_tokens)} tokens"
            )
        frame_value = _parse_number(value_tokens[0], path=name, line=value_number, what="a frame number")
        if frame_value != int(frame_value):
            raise FapFormatError(name, value_number, f"frame number {value_tokens[0]!r} is not an integer")
        if abs(frame_value) > MAX_FRAME_NUMBER:
            raise FapFormatError(name, value_number, f"frame number {value_tokens[0]!r} is past {MAX_FRAME_NUMBER:g} "
                                 "(a day at 1000 fps is under 1e8): not a frame of this file")
        numbers, integer = _value_numbers(value_tokens, value_line, value_number, name)
        if numbers and max(abs(min(numbers)), abs(max(numbers))) > MAX_PLAYABLE_VALUE:
            raise FapFormatError(name, value_number, f"a FAP value beyond +-{MAX_PLAYABLE_VALUE} (2^24, the most "
                                 "players hold exactly and far past any face's motion): not a value a face plays")
        self.integer_values = self.integer_values and integer
        frame_number = int(frame_value)
        if self.first_frame_number is None:
            self.first_frame_number = frame_number
        elif frame_number != self.previous_frame_number + 1:  # type: ignore[operator]
            self.consecutive = False
        self.previous_frame_number = frame_number
        self.frames.append(mask.bits, numbers)

    def notes(self, header_frames: int | None) -> list[str]:
        """The irregularities of the frames read, one sentence each."""
        notes = []
        if self.high_level:
            notes.append(f"{self.high_level} frame(s) with FAP 1 (viseme) or FAP 2 (expression) in their "
                         "multi-value form: the selected viseme / expression number was kept")
        if self.wide_masks:
            notes.append(f"{self.wide_masks} mask line(s) with {N_FAPS + 1} tokens (a known Greta writer bug): "
                         "the extra token was ignored")
        if self.first_frame_number is not None:
            if self.first_frame_number != 0:
                notes.append(f"frame numbers start at {self.first_frame_number}, not 0: frames renumbered from 0")
            if not self.consecutive:
                notes.append("frame numbers are not consecutive: frames taken in file order")
        count = self.frames.count
        if header_frames is not None and header_frames != count:
            notes.append(f"header promises {header_frames} frames but the file holds {count}: all {count} were read")
        if not self.integer_values:
            notes.append("non-integer FAP values (players expect integers)")
        return notes


class FapNameWarning(UserWarning):
    """The stream's name was changed to fit the header players read (ASCII, at most 100 bytes)."""


#: Longest header name written: two players keep the header line in a 256-byte buffer.
MAX_HEADER_NAME = 100
#: Largest FAP value written or read: Xface stores values as float32, exact up to 2**24 (and no face shows more).
MAX_PLAYABLE_VALUE = 2**24
#: Largest frame number read.
MAX_FRAME_NUMBER = 1e9


def _header_name(name: str) -> str:
    """Whitespace to ``_``, non-ASCII characters to ``_`` (players read the header as Latin-1 bytes), at
    most 100 characters; a change other than the whitespace is said with a :class:`FapNameWarning`."""
    cleaned = re.sub(r"\s+", "_", name.strip())
    ascii_name = re.sub(r"[^\x21-\x7e]", "_", cleaned)[:MAX_HEADER_NAME]
    if ascii_name != cleaned:
        warnings.warn(f"the .fap header name {cleaned!r} was written as {ascii_name!r} (players read at most "
                      f"{MAX_HEADER_NAME} ASCII characters there)", FapNameWarning, stacklevel=4)
    return ascii_name or "stream"


def _fap_lines(stream: FapStream, *, name: str | None = None) -> Iterator[str]:
    """The lines of :func:`format_fap`, each with its newline, produced one frame at a time."""
    if not FPS_RANGE[0] <= stream.fps <= FPS_RANGE[1]:
        raise FapWriteError(f"frame rate {stream.fps!r} is outside {FPS_RANGE[0]:g}-{FPS_RANGE[1]:g} fps, the rates a "
                            ".fap reader accepts (this one's included)")
    if stream.fps != int(stream.fps):
        raise FapWriteError(
            f"frame rate {stream.fps!r} is not an integer: the .fap header carries integer fps; write at an "
            "integer rate (fps=25 or 30, or FapStream.resampled)"
        )
    if stream.n_frames == 0:
        raise FapWriteError("the stream has no frame: players cannot play an empty .fap file")
    # only the FAPs active somewhere are touched: a 2-hour stream is 117 MB a copy at 68 columns
    columns = np.flatnonzero(stream.mask.any(axis=0))
    columns = columns[columns >= 2]  # FAP 1 and 2 (viseme, expression) need multi-value syntax players disagree on
    mask = stream.mask[:, columns]
    rounded = np.rint(stream.values[:, columns])
    if np.any(np.abs(rounded[mask]) > MAX_PLAYABLE_VALUE):
        largest = float(np.abs(rounded[mask]).max())
        raise FapWriteError(f"a FAP value of {largest:.0f} exceeds {MAX_PLAYABLE_VALUE} (2^24), the largest a "
                            "player stores exactly and far beyond any face's motion; lower the gains")
    integers = rounded.astype(np.int64)
    yield f"2.1 {_header_name(name if name is not None else stream.name)} {int(stream.fps)} {stream.n_frames}\n"
    mask_lines: dict[bytes, str] = {}  # streams keep one mask for long stretches: format each mask once
    for k in range(stream.n_frames):
        bits = mask[k]
        key = bits.tobytes()
        mask_line = mask_lines.get(key)
        if mask_line is None:
            tokens = ["0"] * N_FAPS
            for column in columns[bits]:
                tokens[column] = "1"
            mask_line = mask_lines[key] = " ".join(tokens) + " \n"
        yield mask_line
        # each mask and value line ends with a space, as Greta's own writer does: C++ Greta's buffer reader
        # (FAPdata::ReadFapBuffer) steps from space to space and misreads a line without it
        yield " ".join([str(k), *map(str, integers[k, bits].tolist())]) + " \n"


def format_fap(stream: FapStream, *, name: str | None = None) -> str:
    """The text of a .fap file in the interoperable subset (see the module docstring).

    Values are rounded to the nearest integer with :func:`numpy.rint` (halves to even); FAP 1 and 2 are
    masked off; whitespace in the name becomes ``_``.

    Raises
    ------
    FapWriteError
        For a non-integer frame rate, no frame, or a value beyond :data:`MAX_PLAYABLE_VALUE` (2^24).
    """
    return "".join(_fap_lines(stream, name=name))


def write_fap(stream: FapStream, path: str | os.PathLike[str], *, name: str | None = None) -> None:
    """Write ``stream`` to ``path`` atomically, in the subset every checked player reads (:func:`format_fap`).

    Parameters
    ----------
    stream : FapStream
        The frames to write.
    path : path-like
        The .fap file; replaced only once it is complete.
    name : str, optional
        The header's stream name (default: the file's stem); a name players cannot read is changed, with a
        :class:`FapNameWarning`.
    """
    lines = _fap_lines(stream, name=name if name is not None else Path(path).stem)
    first = next(lines)  # a stream that cannot be written fails before any file is opened
    with atomic_write(path, newline="\n") as handle:
        handle.write(first)
        handle.writelines(lines)  # frame by frame: hours of frames never sit in memory as one text
