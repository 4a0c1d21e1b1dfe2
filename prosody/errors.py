"""Exceptions raised by :mod:`prosody`.

One root catches everything the project raises on purpose: :class:`VisualProsodyError` (from
:mod:`audio_features`, re-exported here). Every error of this package derives from :class:`ProsodyError`;
those caused by a bad value also derive from :class:`ValueError`, a missing tool from :class:`OSError`. A bad
parameter is a :class:`ConfigError`, which is also ``audio_features.ParameterError``: one class for both
packages' bad parameters. The CLI turns them into one line on stderr and an exit code (2 for a bad parameter,
1 for the rest).
"""

from __future__ import annotations

from audio_features.errors import MissingExtraError, ParameterError, ParameterNote, VisualProsodyError, require_extra

__all__ = ["BallotError", "ConfigError", "FapFormatError", "FapIrregularityWarning", "FapWriteError",
           "GroundTruthError", "MissingExtraError", "ModelError", "ParameterError", "ParameterNote", "PhotoError",
           "PreviewError", "ProsodyError", "TrackingError", "UnknownFapError", "VisualProsodyError", "require_extra"]


class ProsodyError(VisualProsodyError):
    """Base class of every error raised on purpose by :mod:`prosody`."""


class ConfigError(ProsodyError, ParameterError):
    """A parameter or option is outside its documented range (a usage error: exit code 2)."""


class UnknownFapError(ProsodyError, KeyError):
    """A FAP number or name that MPEG-4 does not define."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class PreviewError(ProsodyError, OSError):
    """A preview cannot be made: no ffmpeg, ffmpeg failed, or a GIF too long to hold."""


class PhotoError(ProsodyError, ValueError):
    """A photo cannot become the head: unreadable or too large, no face, a face too small or turned too far,
    or the packages that find faces missing (the message says how to install them)."""


class FapIrregularityWarning(UserWarning):
    """A .fap file is irregular but readable (comments, 69-token masks, renumbered frames, ...); what was
    done about it is said. ``read_fap(..., strict=True)`` makes these errors."""


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


class TrackingError(ProsodyError, ValueError):
    """A video cannot be tracked: unreadable, without the picture or sound asked for, or the tracker's
    packages are missing (the message says how to install them)."""
