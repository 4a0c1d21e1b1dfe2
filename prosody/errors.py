"""Exceptions raised by :mod:`prosody`.

Every error raised on purpose derives from :class:`ProsodyError`; those caused by a bad value also derive
from :class:`ValueError`. The CLI turns them into one line on stderr and an exit code.
"""

from __future__ import annotations


class ProsodyError(Exception):
    """Base class of every error raised on purpose by :mod:`prosody`."""


class ConfigError(ProsodyError, ValueError):
    """A parameter or option is outside its documented range (a usage error: exit code 2)."""


class FapFormatError(ProsodyError, ValueError):
    """A .fap file is malformed; the message names the file, the line and what was expected."""

    def __init__(self, path: str, line: int | None, problem: str) -> None:
        where = f"{path}, line {line}" if line is not None else path
        super().__init__(f"{where}: {problem}")
        self.path = path
        self.line = line


class FapWriteError(ProsodyError, ValueError):
    """A stream cannot be written in the requested format (for example a non-integer frame rate)."""


class GroundTruthError(ProsodyError, ValueError):
    """A ground-truth motion file is malformed or does not match the audio."""


class ModelError(ProsodyError, ValueError):
    """A head-motion model file is malformed, of an unknown version, or unstable."""


class BallotError(ProsodyError, ValueError):
    """A perceptual-study ballot file is malformed; the message lists the offending rows."""
