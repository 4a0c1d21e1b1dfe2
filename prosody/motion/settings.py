"""The settings a conversion shares with a comparison and a live stream, declared once.

Four groups, each a frozen dataclass whose fields carry their default, their type and their documentation:

- :class:`AnalysisSettings`: how the recording is analysed (frame rate, pitch range);
- :class:`MotionSettings`: the head model and its seed, the brow rule, the expressivity controls;
- :class:`FaceSettings`: the lips, the transcript and its language, expressions and emotional states;
- :class:`ChannelSettings`: the gain of each channel and the channels left out.

:func:`takes_settings` gives a function that takes a group both ways: as one object
(``convert(audio, face=FaceSettings(lips="acoustic"))``) or as its fields, one keyword each
(``convert(audio, lips="acoustic")``); keywords override the object's fields. The function's signature and its
numpydoc ``Parameters`` are made from the fields, so :func:`prosody.jobs.pipeline.convert`,
:func:`prosody.evaluation.compare.compare` and :class:`prosody.live.converter.LiveConverter` never type a
setting again.

Examples
--------
>>> FaceSettings(lips="combined").lips
'combined'
>>> ChannelSettings(gains={"nose": 2.0})
Traceback (most recent call last):
...
prosody.errors.ConfigError: unknown channel(s) 'nose'; choose from pitch, yaw, roll, brows, lips
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import numbers
import os
import textwrap
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, Protocol, TypeVar, cast, overload

from audio_features import DEFAULT_F0_CEILING_HZ, DEFAULT_F0_FLOOR_HZ, DEFAULT_FPS

from ..errors import ConfigError
from ..fap.table import EYEBROW_FAPS, HEAD_FAPS
from ..validate import valid_seed
from .expressions import ExpressionSegment
from .expressivity import Expressivity
from .lips import LIP_FAPS
from .pad import PadSegment

if TYPE_CHECKING:  # named in an annotation only
    from .eyebrows import BrowRule

#: Channels of the intensity controls and the FAPs each one drives.
CHANNELS = {"pitch": HEAD_FAPS[:1], "yaw": HEAD_FAPS[1:2], "roll": HEAD_FAPS[2:], "brows": EYEBROW_FAPS,
            "lips": LIP_FAPS}

#: Ways of making lips: from recognised phones (visemes, the default), from the spectrum (acoustic), or both
#: (combined: their mean, the visemes' closures kept).
LIP_METHODS = ("visemes", "acoustic", "combined")

Group = TypeVar("Group", bound=type)


def setting(default: Any, kind: str, doc: str) -> Any:
    """A settings field: its default, its type as the docs write it, and what it does (one numpydoc entry)."""
    return dataclasses.field(default=default, metadata={"kind": kind, "doc": doc})


def documented_fields(cls: Group) -> Group:
    """The dataclass ``cls`` with a numpydoc ``Parameters`` section made from its fields added to its docstring."""
    group: Any = cls
    entries = ["Parameters", "----------"]
    for f in dataclasses.fields(group):
        entries += [f"{f.name} : {f.metadata['kind']}",
                    *textwrap.wrap(f.metadata["doc"], width=100, initial_indent="    ", subsequent_indent="    ")]
    group.__doc__ = inspect.cleandoc(group.__doc__ or "") + "\n\n" + "\n".join(entries)
    return group


@documented_fields
@dataclasses.dataclass(frozen=True, kw_only=True)
class AnalysisSettings:
    """How a recording is analysed into frames (checked where the audio's sample rate is known)."""

    fps: float = setting(DEFAULT_FPS, "float > 0", "Frame rate of the motion, frames per second.")
    f0_floor_hz: float = setting(DEFAULT_F0_FLOOR_HZ, "float > 0, in Hz", "Lowest pitch looked for.")
    f0_ceiling_hz: float = setting(DEFAULT_F0_CEILING_HZ, "float > f0_floor_hz, in Hz", "Highest pitch looked for.")

    def as_keywords(self) -> dict[str, Any]:
        """The fields as keywords.

        Returns
        -------
        dict
            ``fps``, ``f0_floor_hz`` and ``f0_ceiling_hz``, as :func:`audio_features.extract_features` takes them.
        """
        return {"fps": self.fps, "f0_floor_hz": self.f0_floor_hz, "f0_ceiling_hz": self.f0_ceiling_hz}


@documented_fields
@dataclasses.dataclass(frozen=True, kw_only=True)
class MotionSettings:
    """What moves the head and the brows."""

    #: Offline or live by the function that takes it (``resolve_head_model`` or ``live_head_model`` checks it).
    model: Any = setting(
        None, "head model, shipped name or path, optional",
        "Head model of the speech-driven condition: the shipped prosodic generator when omitted; offline also "
        "``\"arx\"`` for the thesis's ARX model, ``\"pad\"`` for Jia et al.'s gestures, or a file from ``prosody "
        "train``.")
    seed: int = setting(0, "int >= 0", "Seed of the stochastic heads (the default generator, Perlin noise).")
    eyebrow_rule: BrowRule | None = setting(None, "AccentRule or EyebrowRule, optional",
                                "The brow rule (default: the accent rule; ``EyebrowRule()`` is the thesis's 207 Hz "
                                "rule).")
    expressivity: Expressivity | None = setting(
        None, "Expressivity, optional", "Greta's six expressivity controls on the generated head and brows (see "
        ":mod:`prosody.motion.expressivity`); ``Expressivity.still()`` keeps only an idle sway.")

    def __post_init__(self) -> None:
        valid_seed(self.seed)
        if self.expressivity is not None and not isinstance(self.expressivity, Expressivity):
            raise ConfigError(f"expressivity must be an Expressivity, got {self.expressivity!r}")


@documented_fields
@dataclasses.dataclass(frozen=True, kw_only=True)
class FaceSettings:
    """What the face shows besides the head and brows: lips, expressions, emotional states."""

    lips: str | None = setting("visemes", "{\"visemes\", \"acoustic\", \"combined\"} or None",
                               "How the lips move: phones -> visemes (default), the acoustic mouth model, both "
                               "averaged, or None for no lip FAPs.")
    transcript: str | None = setting(None, "str or path, optional",
                                     "What is said (text, or a text file), aligned to the audio for the visemes.")
    language: str | None = setting(None, "str, optional",
                                   "The transcript's language as an eSpeak NG code (``es``, ``fr``, ``cmn``, ...; "
                                   "``prosody languages`` lists them); default: English, aligned by PocketSphinx.")
    mouth_model: str | os.PathLike[str] | None = setting(
        None, "path, optional", "A mouth model from ``prosody train --kind mouth`` for ``lips=\"acoustic\"`` or "
        "``\"combined\"`` (default: the shipped one).")
    expression: str | Sequence[ExpressionSegment] | None = setting(
        None, "str or sequence of ExpressionSegment, optional",
        "``NAME:INTENSITY`` for the whole recording (``joy:0.6``), a CSV file of timed expressions, or segments.")
    pad: str | Sequence[PadSegment] | None = setting(
        None, "str or sequence of PadSegment, optional",
        "An emotional state: ``P,A,D`` for the whole recording, a CSV file of timed states, or segments. It shows on "
        "the face as Jia et al.'s partial expressions (brows raised or squeezed, eyes opened), and it drives "
        "``model=\"pad\"``'s gestures (see :mod:`prosody.motion.pad`).")
    pad_map: str | os.PathLike[str] | None = setting(
        None, "path, optional", "A JSON file replacing the default map of PAD states to partial expressions.")

    def __post_init__(self) -> None:
        if self.lips is not None and self.lips not in LIP_METHODS:
            raise ConfigError(f"unknown lip method {self.lips!r}; choose {', '.join(LIP_METHODS)} (or None)")
        # settings the lips would ignore are refused (the messages name the parameters)
        lips = self.lips or "none"
        if self.transcript is not None and lips not in ("visemes", "combined"):
            raise ConfigError(f"transcript= is read by the visemes; it is not used by lips={lips}")
        if self.language is not None and self.transcript is None:
            raise ConfigError("language= is the transcript's language: give transcript= too (without one, "
                              "lips=acoustic follows any language)")
        if self.mouth_model is not None and lips not in ("acoustic", "combined"):
            raise ConfigError(f"mouth_model= is the model of lips=acoustic (or combined); it is not used by "
                              f"lips={lips}")
        if self.pad_map is not None and self.pad is None:
            raise ConfigError("pad_map= maps the state of pad= to the face; give pad= too")
        if self.language is not None:  # before any work: nothing eSpeak NG does not list reaches it
            from audio_features.espeak import check_language

            check_language(self.language)


#: The largest gain of a channel (the head and brows are then kept within what a person can do).
MAX_GAIN = 100.0


@documented_fields
@dataclasses.dataclass(frozen=True, kw_only=True)
class ChannelSettings:
    """How strongly each channel moves, and which ones are left out."""

    gains: Mapping[str, float] | None = setting(
        None, "mapping, optional", "Intensity per channel (``pitch``, ``yaw``, ``roll``, ``brows``, ``lips``): 1 "
        "leaves it, 0.5 halves it.")
    disabled: Iterable[str] = setting((), "iterable of str", "Channels to leave out of the output.")

    def __post_init__(self) -> None:
        if self.gains is not None and not isinstance(self.gains, Mapping):
            raise ConfigError(f"gains map channel names to numbers (e.g. {{'pitch': 0.5}}), got {self.gains!r}")
        gains = dict(self.gains or {})
        # one channel's name alone is that channel, not its letters
        disabled = (self.disabled,) if isinstance(self.disabled, str) else tuple(self.disabled)
        unknown = [name for name in [*gains, *disabled] if name not in CHANNELS]
        if unknown:
            raise ConfigError(f"unknown channel(s) {', '.join(map(repr, unknown))}; choose from {', '.join(CHANNELS)}")
        for name, gain in gains.items():
            if isinstance(gain, bool) or not isinstance(gain, numbers.Real) or not 0 <= gain <= MAX_GAIN:
                raise ConfigError(f"gain of {name!r} must be a number from 0 to {MAX_GAIN:g} (1 keeps the motion, "
                                  f"0 stills it), got {gain!r}")
        object.__setattr__(self, "gains", gains)
        object.__setattr__(self, "disabled", disabled)

    def gain(self, channel: str) -> float:
        """The gain of a channel.

        Parameters
        ----------
        channel : str
            One of :data:`CHANNELS`.

        Returns
        -------
        float
            Its gain (1 where none was given).
        """
        return float(self.gains.get(channel, 1.0))  # type: ignore[union-attr]

    def disabled_faps(self) -> set[int]:
        """The FAPs of the channels left out.

        Returns
        -------
        set of int
        """
        return {fap for name in self.disabled for fap in CHANNELS[name]}

    def applied(self, stream, *, rest: Mapping[int, float] | None = None):
        """``stream`` with each channel's motion (pitch, yaw, roll, brows) times its gain about the rest pose,
        and the channels left out masked off entirely (absent from the output, not zero). The lips' gain is
        applied where they are made (it scales the mouth's shapes, not a mixed expression).

        Parameters
        ----------
        stream : FapStream
        rest : mapping FAP -> value, optional
            The rest pose the gains scale about (0 where not given).

        Returns
        -------
        FapStream
        """
        stream = stream.scaled({fap: self.gain(name) for name in self.gains or {} if name != "lips"
                                for fap in CHANNELS[name]}, about=rest)
        return stream.without(sorted(self.disabled_faps()))


Result = TypeVar("Result")
Class = TypeVar("Class", bound=type)


class _Decorator(Protocol):
    """What :func:`takes_settings` returns: a function keeps its return type (its keywords are not checked
    statically), a class stays itself."""

    @overload
    def __call__(self, target: Class) -> Class: ...

    @overload
    def __call__(self, target: Callable[..., Result]) -> Callable[..., Result]: ...


def takes_settings(**groups: type) -> _Decorator:
    """Let a function (or a class's constructor) take each settings group (``name=SettingsClass``) as one
    object or as its fields.

    The function is written with one keyword-only parameter per group and no default (``analysis:
    AnalysisSettings``). The wrapper offers it as optional, accepts every field of the group as a keyword, builds
    the group from them (over the object when one is given too) and passes it on, so the function always
    receives a complete, checked group. The wrapper's signature and docstring list the fields, from the
    dataclasses.

    Parameters
    ----------
    **groups : type
        Parameter name -> settings dataclass.

    Returns
    -------
    callable
        The decorator.
    """
    fields = {name: [f for f in dataclasses.fields(kind) if f.init] for name, kind in groups.items()}

    def decorate(function: Any) -> Any:
        if isinstance(function, type):  # a class: its __init__ takes them, its docstring documents them
            function.__init__ = decorate(function.__init__)  # type: ignore[misc]
            function.__doc__ = _with_field_docs(inspect.cleandoc(function.__doc__ or ""), fields)
            return function
        own = inspect.signature(function)
        owner = {f.name: group for group, group_fields in fields.items() for f in group_fields}
        clashes = sorted(set(owner) & set(own.parameters))
        if clashes or len(owner) != sum(map(len, fields.values())):
            raise TypeError(f"{function.__qualname__}: settings fields clash: {clashes or 'between groups'}")

        @functools.wraps(function)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            picked: dict[str, dict[str, Any]] = {group: {} for group in groups}
            for name in [name for name in kwargs if name in owner]:
                picked[owner[name]][name] = kwargs.pop(name)
            for group, kind in groups.items():
                given = kwargs.get(group)
                if given is None:
                    kwargs[group] = kind(**picked[group])
                elif isinstance(given, kind):
                    kwargs[group] = dataclasses.replace(cast(Any, given), **picked[group])
                else:
                    raise ConfigError(f"{group} must be a {kind.__name__}, got {given!r}")
            return function(*args, **kwargs)

        flat = [inspect.Parameter(f.name, inspect.Parameter.KEYWORD_ONLY, default=f.default, annotation=f.type)
                for group_fields in fields.values() for f in group_fields]
        parameters = [p.replace(default=None, annotation=f"{p.annotation} | None") if p.name in groups else p
                      for p in own.parameters.values()]
        keep = [p for p in parameters if p.kind is not inspect.Parameter.VAR_KEYWORD]
        wrapper.__signature__ = own.replace(  # type: ignore[attr-defined]
            parameters=keep + flat + [p for p in parameters if p.kind is inspect.Parameter.VAR_KEYWORD])
        if function.__name__ != "__init__":
            wrapper.__doc__ = _with_field_docs(inspect.getdoc(function) or "", fields)
        return wrapper

    return cast(_Decorator, decorate)


def _with_field_docs(doc: str, fields: Mapping[str, list[dataclasses.Field]]) -> str:
    """``doc`` with each group's fields documented after the last entry of its ``Parameters`` section."""
    entries = []
    for group, group_fields in fields.items():
        for f in group_fields:
            text = f"{f.metadata['doc']} A field of ``{group}``, which it overrides."
            entries += [f"{f.name} : {f.metadata['kind']}",
                        *textwrap.wrap(text, width=100, initial_indent="    ", subsequent_indent="    ")]
    lines = doc.splitlines()
    if "Parameters" not in lines:
        raise TypeError("a function that takes settings documents its Parameters (numpydoc)")
    end = lines.index("Parameters") + 2
    while end < len(lines) and not (lines[end] and end + 1 < len(lines) and set(lines[end + 1]) == {"-"}):
        end += 1
    while end > 0 and not lines[end - 1].strip():
        end -= 1
    return "\n".join(lines[:end] + entries + lines[end:])
