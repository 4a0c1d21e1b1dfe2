"""Exceptions raised by :mod:`audio_features`.

Every error the package raises on purpose derives from :class:`AudioFeaturesError`; the ones caused by a
bad value also derive from :class:`ValueError`, so callers' ``except ValueError`` keeps working.
"""

from __future__ import annotations


class AudioFeaturesError(Exception):
    """Base class of every error raised on purpose by :mod:`audio_features`."""


class AudioLoadError(AudioFeaturesError, ValueError):
    """The input is not usable audio: missing, unreadable, empty, truncated, too short or non-finite."""


class ParameterError(AudioFeaturesError, ValueError):
    """A parameter is outside its documented range."""


class NoVoicedFramesWarning(UserWarning):
    """The pitch tracker found no voiced frame; the conditioned F0 is 0 everywhere."""
