"""The settings a conversion shares with a comparison and a live stream, declared once.

Four groups, each a frozen dataclass whose fields carry their default, their type and their documentation:

- :class:`AnalysisSettings`: how the recording is analysed (frame rate, pitch range);
- :class:`MotionSettings`: the head model and its seed, the brow rule, the expressivity controls;
- :class:`FaceSettings`: the lips, the transcript and its language, expressions and emotional states;
- :class:`ChannelSettings`: the gain of each channel and the channels left out.

A function takes a group both ways: as one object (``convert(audio, face=FaceSettings(lips="acoustic"))``) or as
its fields, one keyword each (``convert(audio, lips="acoustic")``); keywords override the object's fields. Its
signature says so in the source: each group a parameter with its defaults, and ``**fields:
Unpack[SettingsFields]``, the typed dictionary of every field, so a type checker sees every keyword and its
type; :func:`overridden` applies the keywords to each group. :func:`make_face` makes a recording's face (lips,
expression, PAD state) from its face group.

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
import inspect
import numbers
import os
import textwrap
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple, TypedDict, TypeVar, cast

from audio_features import DEFAULT_F0_CEILING_HZ, DEFAULT_F0_FLOOR_HZ, DEFAULT_FPS

from ..errors import ConfigError
from ..fap.table import EYEBROW_FAPS, HEAD_FAPS
from ..validate import valid_seed
from .expressivity import Expressivity
from .face.expressions import ExpressionSegment, parse_expressions
from .face.layer import FaceLayer, face_layer
from .face.lips import LIP_FAPS, LIP_METHODS
from .face.pad import PadSegment, parse_pad, read_face_map

if TYPE_CHECKING:  # named in an annotation only
    from .eyebrows import BrowRule

#: Channels of the intensity controls and the FAPs each one drives.
CHANNELS = {"pitch": HEAD_FAPS[:1], "yaw": HEAD_FAPS[1:2], "roll": HEAD_FAPS[2:], "brows": EYEBROW_FAPS,
            "lips": LIP_FAPS}


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
    workers: int = setting(1, "int >= 1", "Processes that analyse a recording's minutes side by side (on Linux, at "
                           "most one per core; the features are the same to the last bit). A recording as it "
                           "streams live is analysed in its own process whatever this says.")

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
        "``model=\"pad\"``'s gestures (see :mod:`prosody.motion.face.pad`).")
    pad_map: str | os.PathLike[str] | None = setting(
        None, "path, optional", "A JSON file replacing the default map of PAD states to partial expressions.")

    def __post_init__(self) -> None:
        if self.lips is not None and self.lips not in LIP_METHODS:
            raise ConfigError(f"unknown lip method {self.lips!r}; choose {', '.join(LIP_METHODS)} (or None)")
        # settings the lips would ignore are refused (the messages name the parameters)
        lips = self.lips or "none"
        if self.transcript is not None and lips not in ("visemes", "combined"):
            raise ConfigError(f"transcript= is read by the visemes; it is not used by lips={lips}",
                              parameter=("transcript", "lips"))
        if self.language is not None and self.transcript is None:
            raise ConfigError("language= is the transcript's language: give transcript= too (without one, "
                              "lips=acoustic follows any language)", parameter=("language", "transcript", "lips"))
        if self.mouth_model is not None and lips not in ("acoustic", "combined"):
            raise ConfigError(f"mouth_model= is the model of lips=acoustic (or combined); it is not used by "
                              f"lips={lips}", parameter=("mouth_model", "lips"))
        if self.pad_map is not None and self.pad is None:
            raise ConfigError("pad_map= maps the state of pad= to the face; give pad= too",
                              parameter=("pad_map", "pad"))
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

    def check_leaves_output(self, *, lips: bool, face_layer: bool = False) -> None:
        """Refuse to leave out every channel that would move: the output would be empty.

        Parameters
        ----------
        lips : bool
            Whether lips are made (they are a channel only then).
        face_layer : bool
            Whether an expression or an emotional state is shown (it moves the face whatever is left out).

        Raises
        ------
        ConfigError
            Every channel that would move is left out, and nothing else moves.
        """
        moving = {"pitch", "yaw", "roll", "brows"} | ({"lips"} if lips else set())
        if moving <= set(self.disabled) and not face_layer:
            raise ConfigError(f"disabled= leaves out every channel ({', '.join(sorted(moving))}): the output would "
                              "be empty", parameter="disabled")

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


class AnalysisFields(TypedDict, total=False):
    """The fields of :class:`AnalysisSettings` as keywords (``convert(audio, fps=25)``)."""

    fps: float
    f0_floor_hz: float
    f0_ceiling_hz: float
    workers: int


class MotionFields(TypedDict, total=False):
    """The fields of :class:`MotionSettings` as keywords."""

    model: Any
    seed: int
    eyebrow_rule: BrowRule | None
    expressivity: Expressivity | None


class FaceFields(TypedDict, total=False):
    """The fields of :class:`FaceSettings` as keywords."""

    lips: str | None
    transcript: str | None
    language: str | None
    mouth_model: str | os.PathLike[str] | None
    expression: str | Sequence[ExpressionSegment] | None
    pad: str | Sequence[PadSegment] | None
    pad_map: str | os.PathLike[str] | None


class ChannelFields(TypedDict, total=False):
    """The fields of :class:`ChannelSettings` as keywords."""

    gains: Mapping[str, float] | None
    disabled: Iterable[str]


class SettingsFields(AnalysisFields, MotionFields, FaceFields, ChannelFields, total=False):
    """Every group's fields as keywords: what ``convert`` and ``compare`` take besides the groups themselves."""


class LiveFields(AnalysisFields, MotionFields, ChannelFields, total=False):
    """The fields a live conversion takes as keywords (it has no face group)."""


#: Each settings group and the keywords that stand for its fields.
GROUP_FIELDS: dict[type, type] = {AnalysisSettings: AnalysisFields, MotionSettings: MotionFields,
                                  FaceSettings: FaceFields, ChannelSettings: ChannelFields}

Settings = TypeVar("Settings")


def overridden(kind: type[Settings], given: object, fields: dict[str, Any], *, name: str) -> Settings:
    """The settings group ``given`` (a ``kind``; ``None`` for its defaults) with those of ``fields`` that are its
    own, which are taken out of ``fields``.

    A function that takes a group both ways (``face=FaceSettings(lips="acoustic")`` or ``lips="acoustic"``) calls
    this once per group on its ``**fields`` (through :func:`settings_groups`).

    Parameters
    ----------
    kind : type
        The group's dataclass.
    given : kind or None
        The group as passed.
    fields : dict
        The keywords passed; this group's are removed from it.
    name : str
        The group's parameter name, for the error.

    Returns
    -------
    kind
        The group, checked, with the keywords applied.

    Examples
    --------
    >>> keywords = {"fps": 25.0, "lips": "acoustic"}
    >>> overridden(AnalysisSettings, AnalysisSettings(), keywords, name="analysis").fps, keywords
    (25.0, {'lips': 'acoustic'})
    """
    if given is None:
        given = kind()
    if not isinstance(given, kind):
        raise ConfigError(f"{name} must be a {kind.__name__}, got {given!r}", parameter=name)
    own = [f.name for f in dataclasses.fields(cast(Any, kind)) if f.init]
    picked = {key: fields.pop(key) for key in own if key in fields}
    return cast(Settings, dataclasses.replace(cast(Any, given), **picked)) if picked else given


class Groups(NamedTuple):
    """The four settings groups of one call, each complete and checked."""

    analysis: AnalysisSettings
    motion: MotionSettings
    face: FaceSettings
    channels: ChannelSettings


def settings_groups(function: str, fields: Mapping[str, Any], *, analysis: object = None, motion: object = None,
                    face: object = None, channels: object = None,
                    taking: Iterable[str] = ("analysis", "motion", "face", "channels")) -> Groups:
    """The groups a function was given, with its ``**fields`` applied to them by :func:`overridden`.

    Parameters
    ----------
    function : str
        The function's name, for the error on a keyword no group has.
    fields : mapping
        Its ``**fields``.
    analysis, motion, face, channels : the groups as passed (``None``: the defaults)
    taking : iterable of str
        The groups whose fields the function takes as keywords; another group's field is an unknown keyword.

    Returns
    -------
    Groups

    Examples
    --------
    >>> settings_groups("convert", {"seed": 3}).motion.seed
    3
    >>> settings_groups("convert", {"fpss": 25})
    Traceback (most recent call last):
    ...
    TypeError: convert() got an unexpected keyword argument 'fpss'
    """
    left, taken = dict(fields), set(taking)
    given = {"analysis": analysis, "motion": motion, "face": face, "channels": channels}
    groups = Groups(*(overridden(kind, given[name], left if name in taken else {}, name=name)
                      for name, kind in zip(Groups._fields, (AnalysisSettings, MotionSettings, FaceSettings,
                                                             ChannelSettings), strict=True)))
    if left:
        raise TypeError(f"{function}() got an unexpected keyword argument {next(iter(left))!r}")
    return groups


def make_face(audio: str | os.PathLike[str], features, face: FaceSettings,
              channels: ChannelSettings | None = None) -> FaceLayer | None:
    """The lips and expression layer of a recording on its features' grid (None when there is neither).

    ``face`` says what it shows (see :class:`prosody.motion.settings.FaceSettings`); the lips' gain of
    ``channels`` scales the lips, and the lips left out there are not made.
    """
    segments = parse_expressions(face.expression) if isinstance(face.expression, str) else list(face.expression or ())
    states = parse_pad(face.pad) if isinstance(face.pad, str) else list(face.pad or ())
    face_map = read_face_map(face.pad_map)
    channels = channels or ChannelSettings()
    lips = None if "lips" in channels.disabled else face.lips
    if lips is None and not segments and not states:
        return None
    transcript = face.transcript
    if transcript is not None and os.path.isfile(transcript):
        from audio_features.phones import read_transcript

        transcript = read_transcript(transcript)
    model = None
    if face.mouth_model is not None and lips in ("acoustic", "combined"):
        from .face.mouth_model import AcousticMouthModel

        model = AcousticMouthModel.load(face.mouth_model)
    return face_layer(audio, features.n_frames, fps=features.fps, lips=lips, transcript=transcript,
                      lip_gain=channels.gain("lips"), expressions=segments, mouth_model=model,
                      pad=states, pad_map=face_map, language=face.language)
