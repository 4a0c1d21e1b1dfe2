"""Exceptions raised by :mod:`audio_features`, and the root of every error the project raises.

:class:`VisualProsodyError` is the one class a caller catches for everything both packages raise on purpose
(it lives here because :mod:`audio_features` never imports :mod:`prosody`). Every error of this package
derives from :class:`AudioFeaturesError`; the ones caused by a bad value also derive from :class:`ValueError`,
so callers' ``except ValueError`` keeps working. :class:`ParameterError` is also the class of
:mod:`prosody`'s bad parameters (``prosody.errors.ConfigError`` derives from it).
"""

from __future__ import annotations


class VisualProsodyError(Exception):
    """Base class of every error raised on purpose by :mod:`audio_features` and :mod:`prosody`."""


class AudioFeaturesError(VisualProsodyError):
    """Base class of every error raised on purpose by :mod:`audio_features`."""


class AudioLoadError(AudioFeaturesError, ValueError):
    """The input is not usable audio: missing, unreadable, empty, truncated, too short or non-finite."""


class ParameterError(AudioFeaturesError, ValueError):
    """A parameter is outside its documented range (a usage error: the command exits with code 2).

    ``parameter`` names, as data, the parameters the message speaks of by their Python names (one name or a
    tuple): a command line says each by its own option instead (``f0_floor_hz`` -> ``--f0-floor``), from its
    parser, without reading the message for names.

    Examples
    --------
    >>> error = ParameterError("f0_floor_hz must be below f0_ceiling_hz", parameter=("f0_floor_hz", "f0_ceiling_hz"))
    >>> error.parameters
    ('f0_floor_hz', 'f0_ceiling_hz')
    """

    def __init__(self, *args: object, parameter: str | tuple[str, ...] | None = None) -> None:
        super().__init__(*args)
        self.parameters: tuple[str, ...] = (parameter,) if isinstance(parameter, str) else tuple(parameter or ())


class ParameterNote(UserWarning):
    """A warning about a parameter's value, naming the parameters it speaks of as :class:`ParameterError` does
    (``parameter=``), so that a command line can say them by its options."""

    def __init__(self, *args: object, parameter: str | tuple[str, ...] | None = None) -> None:
        super().__init__(*args)
        self.parameters: tuple[str, ...] = (parameter,) if isinstance(parameter, str) else tuple(parameter or ())


class AnalysisError(AudioFeaturesError, RuntimeError):
    """The analysis failed in a way no input should cause (a bug to report)."""


class NoVoicedFramesWarning(UserWarning):
    """The pitch tracker found no voiced frame; the conditioned F0 is 0 everywhere."""


class MissingExtraError(ParameterError):
    """A feature needs a package of an optional extra that is not installed; the message names the extra."""


def require_extra(modules: tuple[str, ...], extra: str, what: str) -> None:
    """Import each of ``modules``, or raise :class:`MissingExtraError` in one line naming ``extra``.

    Parameters
    ----------
    modules : tuple of str
        Importable names the feature needs (``("statsmodels",)``).
    extra : str
        The optional dependency group that installs them (``"stats"``).
    what : str
        What needs them, as the message says it (``"training a head model"``).

    Examples
    --------
    >>> require_extra(("json",), "none", "reading JSON")  # present: nothing happens
    """
    import importlib

    missing = []
    for module in modules:
        try:
            importlib.import_module(module)
        except ImportError:
            missing.append(module)
    if missing:
        raise MissingExtraError(f"{what} needs {' and '.join(missing)}: pip install 'visual-prosody[{extra}]'")
