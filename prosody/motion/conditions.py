"""The four conditions of docs/fap.md, each as a FAP stream computed from a recording's features."""

from __future__ import annotations

import enum
import warnings

import numpy as np

from audio_features import Features

from ..errors import ConfigError, GroundTruthError
from ..fap.stream import FapStream
from ..fap.table import EYEBROW_FAPS, HEAD_FAPS, PROSODY_FAPS
from .expressivity import Expressivity, shape_brows, shape_head
from .eyebrows import BrowRule, EyebrowRaises, brow_raises, warn_if_no_raise
from .heads.models import HeadModel, resolve_head_model, rest_pose
from .perlin import PerlinSettings, perlin_curves


class Condition(str, enum.Enum):
    """The four animation conditions compared by the thesis."""

    NO_PROSODY = "NO_PROSODY"
    RANDOM = "RANDOM"
    SPEECH_DRIVEN = "SPEECH_DRIVEN"
    GROUND_TRUTH = "GROUND_TRUTH"

    @classmethod
    def parse(cls, text: str) -> Condition:
        """Accept the short CLI names (none, random, speech, truth) and the full names."""
        key = text.strip().lower()
        if key in _SHORT_NAMES:
            return _SHORT_NAMES[key]
        try:
            return cls(text.strip().upper())
        except ValueError:
            choices = ", ".join([*_SHORT_NAMES, *(c.value for c in cls)])
            raise ConfigError(f"unknown condition {text!r}; choose one of {choices}") from None


_SHORT_NAMES = {"none": Condition.NO_PROSODY, "random": Condition.RANDOM, "speech": Condition.SPEECH_DRIVEN,
                "truth": Condition.GROUND_TRUTH}
_NAMES = {condition: name for name, condition in _SHORT_NAMES.items()}


def check_condition(condition: Condition | str, *, ground_truth: object = None, model: object = None,
                    expressivity: Expressivity | None = None) -> Condition:
    """Refuse settings the condition would ignore, so the output is never silently other than asked: recorded
    motion is the truth condition's, a head model the speech-driven one's, and the expressivity controls shape
    generated motion (speech or random). The messages name the parameters (``ground_truth=``, ``model=``).

    Parameters
    ----------
    condition : Condition or str
    ground_truth : optional
        Recorded motion given (anything but None).
    model : optional
        A head model given (anything but None).
    expressivity : Expressivity, optional

    Returns
    -------
    Condition
        The condition, parsed.

    Raises
    ------
    ConfigError
        One of the settings does not apply to the condition.
    """
    chosen = condition if isinstance(condition, Condition) else Condition.parse(condition)
    name = _NAMES[chosen]
    if ground_truth is not None and chosen is not Condition.GROUND_TRUTH:
        raise ConfigError(f"ground_truth= is the recorded motion of condition=truth; it is not used by "
                          f"condition={name}", parameter=("ground_truth", "condition"))
    if model is not None and chosen is not Condition.SPEECH_DRIVEN:
        raise ConfigError(f"model= is the head model of condition=speech; it is not used by condition={name}",
                          parameter=("model", "condition"))
    if expressivity is not None and not expressivity.is_neutral and chosen in (Condition.NO_PROSODY,
                                                                            Condition.GROUND_TRUTH):
        raise ConfigError(f"the expressivity controls shape generated motion; condition={name} has none (choose "
                          "speech or random)", parameter="condition")
    return chosen
#: The conditions' short names as the commands take them, the default first; live streams have no recording.
CONDITION_NAMES = ("speech", "random", "none", "truth")
LIVE_CONDITION_NAMES = ("speech", "random", "none")
#: Display order of the conditions (the order of the thesis and of the perceptual-study tables).
CONDITION_ORDER = (Condition.NO_PROSODY, Condition.RANDOM, Condition.SPEECH_DRIVEN, Condition.GROUND_TRUTH)


def head_motion(model: HeadModel, features: Features, *, seed: int = 0) -> dict[int, np.ndarray]:
    """A head model's motion on the features' grid: at another frame rate than the model's (25 fps for the
    Java Greta, 29.97 for video), the features are resampled to the model's rate and the motion back."""
    if features.fps == model.fps_:
        return model.generate(features, seed=seed)
    at_model_rate = features.resampled(model.fps_)
    curves = model.generate(at_model_rate, seed=seed)
    model_times = np.arange(at_model_rate.n_frames) / model.fps_
    times = np.arange(features.n_frames) / features.fps
    return {fap: np.interp(times, model_times, curve) if curve.size else np.zeros(features.n_frames)
            for fap, curve in curves.items()}


def expressive(curves: dict[int, np.ndarray], *, fps: float, expressivity: Expressivity | None,
               rest: dict[int, float] | None = None) -> dict[int, np.ndarray]:
    """Generated prosody curves (brows 31-34 in ENS, head 48-50 in AU) shaped by the expressivity controls:
    the head about its rest pose (``rest``, FAP -> AU; 0 when not given), the brows from 31's curve."""
    if expressivity is None or expressivity.is_neutral:
        return curves
    out = dict(curves)
    if all(fap in curves for fap in HEAD_FAPS):
        pose = np.array([(rest or {}).get(fap, 0.0) for fap in HEAD_FAPS])
        motion = np.column_stack([curves[fap] for fap in HEAD_FAPS]) - pose
        shaped = shape_head(motion, fps=fps, expressivity=expressivity) + pose
        out.update({fap: shaped[:, axis] for axis, fap in enumerate(HEAD_FAPS)})
    if all(fap in curves for fap in EYEBROW_FAPS):
        brows = shape_brows(curves[EYEBROW_FAPS[0]], fps=fps, expressivity=expressivity)
        out.update({fap: brows.copy() for fap in EYEBROW_FAPS})
    return out


class MissingMotionWarning(UserWarning):
    """Recorded motion lacks some prosody FAPs (often the eyebrows): GROUND_TRUTH leaves them masked off."""


def condition_stream(
    condition: Condition,
    features: Features,
    *,
    seed: int = 0,
    model: HeadModel | None = None,
    ground_truth: FapStream | None = None,
    eyebrow_rule: BrowRule | None = None,
    eyebrows: EyebrowRaises | None = None,
    perlin: PerlinSettings | None = None,
    name: str = "prosody",
    expressivity: Expressivity | None = None,
) -> FapStream:
    """The prosody FAPs (31-34, 48-50) of one condition for a recording.

    Parameters
    ----------
    condition : Condition
    features : Features
        The recording's features; the stream has their frame count and rate.
    seed : int >= 0
        Seed of the RANDOM condition's noise and of the default speech-driven head's (same seed, same
        stream).
    model : ArxHeadModel or ProsodicHeadModel, optional
        Head model for SPEECH_DRIVEN; the shipped prosodic generator when omitted.
    ground_truth : FapStream, optional
        Recorded motion on the features' grid (required for GROUND_TRUTH); see
        :func:`prosody.fap.recorded.fit_to_grid`.
    eyebrow_rule : AccentRule or EyebrowRule, optional
        The speech-driven brows' rule: the accent rule (default) or the thesis's rule.
    perlin : PerlinSettings, optional
        Parameters of the noise.
    eyebrows : EyebrowRaises, optional
        The rule's result when the caller already has it (SPEECH_DRIVEN; ``eyebrow_rule`` is then unused).
    expressivity : Expressivity, optional
        Greta's expressivity controls on the generated head and brows (RANDOM and SPEECH_DRIVEN; recorded
        motion and the still condition are left as they are).
    """
    n, fps = features.n_frames, features.fps
    if condition is Condition.NO_PROSODY:
        return FapStream.from_curves({fap: np.zeros(n) for fap in PROSODY_FAPS}, fps=fps, name=name, n_frames=n)
    if condition is Condition.RANDOM:
        curves = expressive(perlin_curves(n, fps=fps, seed=seed, settings=perlin), fps=fps,
                            expressivity=expressivity)
        return FapStream.from_curves(curves, fps=fps, name=name, n_frames=n)
    if condition is Condition.SPEECH_DRIVEN:
        model = resolve_head_model(model)
        if eyebrows is None:
            eyebrows = brow_raises(features, eyebrow_rule)
            warn_if_no_raise(eyebrows)
        curves = eyebrows.curves()
        curves.update(head_motion(model, features, seed=seed))
        curves = expressive(curves, fps=fps, expressivity=expressivity, rest=rest_pose(model))
        return FapStream.from_curves(curves, fps=fps, name=name, n_frames=n)
    if ground_truth is None:
        raise ConfigError("the GROUND_TRUTH condition needs recorded motion (ground_truth=FILE)",
                          parameter="ground_truth")
    if ground_truth.n_frames != n or ground_truth.fps != fps:
        raise GroundTruthError("recorded motion must be on the features' frame grid (use fit_to_grid)")
    stream = ground_truth.select(PROSODY_FAPS).renamed(name)
    if not set(HEAD_FAPS) <= set(stream.active_faps):
        warnings.warn("recorded motion has no head rotation (FAP 48-50)", MissingMotionWarning, stacklevel=2)
    if not set(EYEBROW_FAPS) & set(stream.active_faps):
        warnings.warn("recorded motion has no eyebrow FAPs (31-34): they stay masked off in GROUND_TRUTH",
                      MissingMotionWarning, stacklevel=2)
    return stream
