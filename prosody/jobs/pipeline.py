"""One call per job: audio in, FAP stream (and file) out. The CLI is a thin shell over these."""

from __future__ import annotations

import dataclasses
import os
import warnings
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from audio_features import DEFAULT_FPS, Features, extract_features

from ..errors import ConfigError, ParameterNote
from ..fap.fapfile import read_fap
from ..fap.mouth_cues import CUE_FPS
from ..fap.recorded import fit_to_grid, read_motion
from ..fap.stream import FapStream
from ..fap.table import EYEBROW_FAPS
from ..motion.conditions import Condition, check_condition, condition_stream
from ..motion.face.layer import FaceLayer
from ..motion.face.pad import parse_pad
from ..motion.heads.models import resolve_head_model, rest_pose
from ..motion.heads.pad import PadHeadModel
from ..motion.limits import warn_if_bent, within_human_limits
from ..motion.perlin import PerlinSettings
from ..motion.settings import (
    CHANNELS,
    AnalysisSettings,
    ChannelFields,
    ChannelSettings,
    FaceSettings,
    MotionSettings,
    SettingsFields,
    make_face,
    settings_groups,
)

if TYPE_CHECKING:  # the keywords' types, for a type checker
    from typing_extensions import Unpack

__all__ = ["CHANNELS", "BaseResampledWarning", "apply_controls", "convert", "load_ground_truth"]


class BaseResampledWarning(ParameterNote):
    """A ``base`` .fap at another frame rate than the output was resampled to it (it names ``fps``)."""


def apply_controls(stream: FapStream, *, rest: Mapping[int, float] | None = None,
                   channels: ChannelSettings = ChannelSettings(), **fields: Unpack[ChannelFields]) -> FapStream:
    """Per-channel intensity: multiply each channel's motion (pitch, yaw, roll, brows) by its gain about the
    rest pose, and mask the disabled channels off entirely (they are then absent from the output, not zero).

    Parameters
    ----------
    stream : FapStream
        The motion to control.
    rest : mapping FAP -> value, optional
        The rest pose the gains scale about (0 where not given).
    channels : ChannelSettings, optional
        The gains and the channels left out; or its fields as keywords.
    **fields
        ``gains`` and ``disabled``, overriding those of ``channels``.

    Returns
    -------
    FapStream
    """
    channels = settings_groups("apply_controls", fields, channels=channels, taking=("channels",)).channels
    return channels.applied(stream, rest=rest)


def load_ground_truth(path: str | os.PathLike[str], features: Features) -> FapStream:
    """Recorded motion (.head.csv or .fap) on the features' grid."""
    return fit_to_grid(read_motion(path), n_frames=features.n_frames, fps=features.fps, source=str(path))


def convert(
    audio: str | os.PathLike[str],
    output: str | os.PathLike[str] | None = None,
    *,
    condition: Condition | str = Condition.SPEECH_DRIVEN,
    ground_truth: str | os.PathLike[str] | None = None,
    base: str | os.PathLike[str] | None = None,
    perlin: PerlinSettings | None = None,
    output_format: str | None = None,
    features: Features | None = None,
    progress: Callable[[int, int], None] | None = None,
    analysis: AnalysisSettings = AnalysisSettings(),
    motion: MotionSettings = MotionSettings(),
    face: FaceSettings = FaceSettings(),
    channels: ChannelSettings = ChannelSettings(),
    **fields: Unpack[SettingsFields],
) -> FapStream:
    """Convert a speech recording into the FAP stream of one condition, and write it if ``output`` is given.

    Parameters
    ----------
    audio : path
        Speech recording.
    output : path, optional
        File to write; the format comes from ``output_format`` or the extension (``.fap``, ...). The mouth cues'
        formats (``.rhubarb.json``, ``.dat``, ...) are made at 100 frames a second
        (:data:`prosody.fap.mouth_cues.CUE_FPS`), so that the cues sit on Rhubarb Lip Sync's 0.01 s grid, unless
        ``fps`` is given as a keyword (or another than the default in ``analysis``).
    condition : Condition or str
        ``speech`` (default), ``random``, ``none`` or ``truth`` (or the full names).
    ground_truth : path, optional
        Recorded motion (``.head.csv`` or ``.fap``); required for ``truth``.
    base : path, optional
        A .fap recording of the same speech (its length within two frames of the audio's) whose other FAPs
        (lips, eyes) are carried into the output.
    perlin : PerlinSettings, optional
        The noise of the ``random`` condition (default: the thesis's).
    output_format : str, optional
        A name of :data:`prosody.outputs.WRITERS` (fap, csv, csv-physical, json, bvh, livelink, the mouth
        cues' formats, gltf).
    features : Features, optional
        Already extracted features of ``audio`` (skips the analysis).
    progress : callable, optional
        Called as ``progress(frames_done, frames_total)`` during the analysis, the long part of a conversion.
    analysis : AnalysisSettings, optional
        How the recording is analysed; or give its fields as keywords (below).
    motion : MotionSettings, optional
        The head model, its seed, the brow rule and the expressivity controls; or its fields as keywords.
    face : FaceSettings, optional
        The lips, the transcript, expressions and emotional states; or its fields as keywords.
    channels : ChannelSettings, optional
        Gains and channels left out; or its fields as keywords.
    **fields
        Any field of the groups above by its name, overriding that group's: ``fps``, ``f0_floor_hz``,
        ``f0_ceiling_hz``, ``workers`` (analysis); ``model``, ``seed``, ``eyebrow_rule``, ``expressivity``
        (motion); ``lips``, ``transcript``, ``language``, ``mouth_model``, ``expression``, ``pad``, ``pad_map``
        (face); ``gains``, ``disabled`` (channels). Typed by :class:`~prosody.motion.settings.SettingsFields`.

    Returns
    -------
    FapStream
    """
    if output is not None and not os.fspath(output):
        raise ConfigError("output: no output file name given")
    if _writes_cues_at_the_default_rate(output, output_format, features, analysis, fields):
        fields["fps"] = CUE_FPS  # mouth cues on Rhubarb's 0.01 s grid
    analysis, motion, face, channels = settings_groups("convert", fields, analysis=analysis, motion=motion, face=face,
                                                       channels=channels)
    channels.check_leaves_output(lips=face.lips is not None, face_layer=bool(face.expression or face.pad))
    chosen = check_condition(condition, ground_truth=ground_truth, model=motion.model,
                             expressivity=motion.expressivity)
    if features is None:
        features = extract_features(audio, **analysis.as_keywords(), workers=analysis.workers, progress=progress)
    head_model = resolve_head_model(motion.model) if chosen is Condition.SPEECH_DRIVEN else None
    states = parse_pad(face.pad) if isinstance(face.pad, str) else list(face.pad or ())
    if states and isinstance(head_model, PadHeadModel):
        head_model = head_model.with_states(states)
    truth = load_ground_truth(ground_truth, features) if ground_truth is not None else None
    name = Path(output).stem if output is not None else Path(str(audio)).stem
    stream = condition_stream(chosen, features, seed=motion.seed, model=head_model, ground_truth=truth,
                              eyebrow_rule=motion.eyebrow_rule, perlin=perlin, name=name,
                              expressivity=motion.expressivity)
    layer = make_face(audio, features, dataclasses.replace(face, pad=states), channels)
    recorded = _base_motion(base, stream) if base is not None else None
    if layer is not None and recorded is not None:
        # the base's own lips (a recording's) are kept: generated lips fill only what it lacks
        layer = FaceLayer({fap: curve for fap, curve in layer.curves.items() if fap not in recorded.active_faps})
    if layer is not None:
        stream = layer.over(stream)
    # gains scale motion about the rest pose: a model's resting lean is not motion
    stream = apply_controls(stream, channels=channels, rest=rest_pose(head_model) if head_model is not None else None)
    if chosen is not Condition.GROUND_TRUTH:  # what a person did is never bent
        stream, bent = within_human_limits(stream)
        warn_if_bent(bent, stacklevel=2)
    if recorded is not None:
        stream = stream.merged_over(recorded)
    if output is not None:
        from ..outputs import write_stream

        write_stream(stream, output, output_format, sound_file=audio, duration_s=features.duration_s)
    return stream


def _writes_cues_at_the_default_rate(output, output_format: str | None, features: Features | None,
                                     analysis: AnalysisSettings, fields: Mapping) -> bool:
    """Whether ``convert`` writes mouth cues with no frame rate asked for (none given as a keyword, the default in
    ``analysis``, no features already on a grid): those are made at :data:`CUE_FPS`."""
    if output is None or features is not None or "fps" in fields or analysis.fps != DEFAULT_FPS:
        return False
    from ..outputs import CUE_FORMATS, format_for

    return format_for(output, output_format) in CUE_FORMATS


def _base_motion(base: str | os.PathLike[str], stream: FapStream) -> FapStream:
    """The other FAPs of ``base``, a recording of the same speech, on ``stream``'s grid (its length within two
    frames, like recorded motion); the outer brows left out where ``stream`` has brows of its own."""
    original = read_fap(base).stream
    if original.fps != stream.fps:
        warnings.warn(BaseResampledWarning(f"{base}: the base is at {original.fps:g} fps and is resampled to "
                                           f"{stream.fps:g} fps (give fps={original.fps:g} to keep its rate)",
                                           parameter="fps"), stacklevel=3)
    recorded = fit_to_grid(original, n_frames=stream.n_frames, fps=stream.fps, source=str(base))
    if set(EYEBROW_FAPS) & set(stream.active_faps):
        # the brows are the condition's: the base's outer brows (35, 36) would not match its inner ones
        recorded = recorded.without([35, 36])
    return recorded
