"""One call per job: audio in, FAP stream (and file) out. The CLI is a thin shell over these."""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path

from audio_features import DEFAULT_F0_CEILING_HZ, DEFAULT_F0_FLOOR_HZ, DEFAULT_FPS, Features, extract_features

from ..errors import ConfigError
from ..fap.fapfile import read_fap
from ..fap.stream import FapStream
from ..fap.table import EYEBROW_FAPS, HEAD_FAPS
from ..motion.conditions import Condition, condition_stream
from ..motion.expressions import ExpressionSegment
from ..motion.expressivity import Expressivity
from ..motion.eyebrows import BrowRule
from ..motion.face import FaceLayer, make_face
from ..motion.ground_truth import fit_to_grid, read_motion
from ..motion.head_models import HeadModel, resolve_head_model, rest_pose
from ..motion.limits import warn_if_bent, within_human_limits
from ..motion.lips import LIP_FAPS
from ..motion.pad import PadSegment, parse_pad
from ..motion.pad_head import PadHeadModel
from ..motion.perlin import PerlinSettings

#: Channels of the intensity controls and the FAPs each one drives.
CHANNELS = {"pitch": HEAD_FAPS[:1], "yaw": HEAD_FAPS[1:2], "roll": HEAD_FAPS[2:], "brows": EYEBROW_FAPS,
            "lips": LIP_FAPS}


class BaseResampledWarning(UserWarning):
    """A ``base`` .fap at another frame rate than the output was resampled to it."""


def apply_controls(stream: FapStream, *, gains: Mapping[str, float] | None = None,
                   disabled: Iterable[str] = (), rest: Mapping[int, float] | None = None) -> FapStream:
    """Per-channel intensity: multiply each channel's motion (pitch, yaw, roll, brows) by its gain about the
    rest pose (``rest``: FAP -> value, 0 where not given), and mask the ``disabled`` channels off entirely
    (they are then absent from the output, not zero)."""
    gains = dict(gains or {})
    disabled = list(disabled)
    unknown = [name for name in [*gains, *disabled] if name not in CHANNELS]
    if unknown:
        raise ConfigError(f"unknown channel(s) {', '.join(map(repr, unknown))}; choose from {', '.join(CHANNELS)}")
    # the lips' gain is applied where they are made (it scales the mouth shapes, not the mixed expression)
    stream = stream.scaled({fap: gain for name, gain in gains.items() if name != "lips" for fap in CHANNELS[name]},
                           about=rest)
    return stream.without([fap for name in disabled for fap in CHANNELS[name]])


def load_ground_truth(path: str | os.PathLike[str], features: Features) -> FapStream:
    """Recorded motion (.head.csv or .fap) on the features' grid."""
    return fit_to_grid(read_motion(path), n_frames=features.n_frames, fps=features.fps, source=str(path))


def convert(
    audio: str | os.PathLike[str],
    output: str | os.PathLike[str] | None = None,
    *,
    condition: Condition | str = Condition.SPEECH_DRIVEN,
    ground_truth: str | os.PathLike[str] | None = None,
    model: HeadModel | str | os.PathLike[str] | None = None,
    base: str | os.PathLike[str] | None = None,
    seed: int = 0,
    fps: float = DEFAULT_FPS,
    f0_floor_hz: float = DEFAULT_F0_FLOOR_HZ,
    f0_ceiling_hz: float = DEFAULT_F0_CEILING_HZ,
    eyebrow_rule: BrowRule | None = None,
    perlin: PerlinSettings | None = None,
    output_format: str | None = None,
    gains: Mapping[str, float] | None = None,
    disabled: Iterable[str] = (),
    features: Features | None = None,
    progress: Callable[[int, int], None] | None = None,
    lips: str | None = "visemes",
    transcript: str | None = None,
    expression: str | Sequence[ExpressionSegment] | None = None,
    mouth_model: str | os.PathLike[str] | None = None,
    expressivity: Expressivity | None = None,
    pad: str | Sequence[PadSegment] | None = None,
    pad_map: str | os.PathLike[str] | None = None,
    language: str | None = None,
) -> FapStream:
    """Convert a speech recording into the FAP stream of one condition, and write it if ``output`` is given.

    Parameters
    ----------
    audio : path
        Speech recording.
    output : path, optional
        File to write; the format comes from ``output_format`` or the extension (``.fap``, ...).
    condition : Condition or str
        ``speech`` (default), ``random``, ``none`` or ``truth`` (or the full names).
    ground_truth : path, optional
        Recorded motion (``.head.csv`` or ``.fap``); required for ``truth``.
    model : head model, shipped name or path, optional
        Head model for ``speech``: the shipped prosodic generator when omitted; ``"arx"`` for the
        thesis's ARX model, or a file from ``prosody train``.
    base : path, optional
        A .fap recording of the same speech (its length within two frames of the audio's) whose other FAPs
        (lips, eyes) are carried into the output.
    seed : int >= 0
        Seed of the ``random`` condition and of the default speech-driven head.
    fps : float > 0
        Frame rate of the output.
    output_format : str, optional
        A name of :data:`prosody.fap.exporters.WRITERS` (fap, csv, csv-physical, json, bvh, livelink) or of
        :data:`~prosody.fap.exporters.DEFERRED_WRITERS` (gltf).
    gains : mapping, optional
        Intensity per channel (``pitch``, ``yaw``, ``roll``, ``brows``, ``lips``): 1 leaves it, 0.5 halves it.
    disabled : iterable of str
        Channels to leave out of the output.
    features : Features, optional
        Already extracted features of ``audio`` (skips the analysis).
    progress : callable, optional
        Called as ``progress(frames_done, frames_total)`` during the analysis, the long part of a conversion.
    lips : {"visemes", "acoustic"} or None
        How the lips move (the same in every condition): phones -> visemes (default), the acoustic mouth
        model, or None for no lip FAPs.
    transcript : str or path, optional
        What is said (text, or a text file), aligned to the audio for the visemes.
    language : str, optional
        The transcript's language as an eSpeak NG code (``es``, ``fr``, ``cmn``, ...; ``prosody languages`` lists
        them); default: English, aligned by PocketSphinx.
    expression : str or sequence of ExpressionSegment, optional
        ``NAME:INTENSITY`` for the whole recording (``joy:0.6``), a CSV file of timed expressions, or segments.
    mouth_model : path, optional
        A mouth model from ``prosody train --kind mouth`` for ``lips="acoustic"`` (default: the shipped one).
    expressivity : Expressivity, optional
        Greta's six expressivity controls on the generated head and brows (see
        :mod:`prosody.motion.expressivity`); ``Expressivity.still()`` keeps only an idle sway.
    pad : str or sequence of PadSegment, optional
        An emotional state: ``P,A,D`` for the whole recording, a CSV file of timed states, or segments. It shows
        on the face as seed 000's partial expressions (brows raised or squeezed, eyes opened; ``pad_map``: a JSON
        file replacing the default map), and it drives ``model="pad"``'s gestures (see :mod:`prosody.motion.pad`).

    Returns
    -------
    FapStream
    """
    if output is not None and not os.fspath(output):
        raise ConfigError("output: no output file name given")
    chosen = condition if isinstance(condition, Condition) else Condition.parse(condition)
    if features is None:
        features = extract_features(audio, fps=fps, f0_floor_hz=f0_floor_hz, f0_ceiling_hz=f0_ceiling_hz,
                                    progress=progress)
    head_model = resolve_head_model(model) if chosen is Condition.SPEECH_DRIVEN else None
    states = parse_pad(pad) if isinstance(pad, str) else list(pad or ())
    if states and isinstance(head_model, PadHeadModel):
        head_model = head_model.with_states(states)
    truth = load_ground_truth(ground_truth, features) if ground_truth is not None else None
    name = Path(output).stem if output is not None else Path(str(audio)).stem
    stream = condition_stream(chosen, features, seed=seed, model=head_model, ground_truth=truth,
                              eyebrow_rule=eyebrow_rule, perlin=perlin, name=name, expressivity=expressivity)
    face = make_face(audio, features, lips=lips, transcript=transcript, expression=expression, gains=gains,
                     disabled=disabled, mouth_model=mouth_model, pad=states, pad_map=pad_map, language=language)
    recorded = _base_motion(base, stream) if base is not None else None
    if face is not None and recorded is not None:
        # the base's own lips (a recording's) are kept: generated lips fill only what it lacks
        face = FaceLayer({fap: curve for fap, curve in face.curves.items() if fap not in recorded.active_faps})
    if face is not None:
        stream = face.over(stream)
    # gains scale motion about the rest pose: a model's resting lean is not motion
    stream = apply_controls(stream, gains=gains, disabled=disabled,
                            rest=rest_pose(head_model) if head_model is not None else None)
    if chosen is not Condition.GROUND_TRUTH:  # what a person did is never bent
        stream, bent = within_human_limits(stream)
        warn_if_bent(bent, stacklevel=2)
    if recorded is not None:
        stream = stream.merged_over(recorded)
    if output is not None:
        from ..fap.exporters import write_stream

        write_stream(stream, output, output_format)
    return stream


def _base_motion(base: str | os.PathLike[str], stream: FapStream) -> FapStream:
    """The other FAPs of ``base``, a recording of the same speech, on ``stream``'s grid (its length within two
    frames, like recorded motion); the outer brows left out where ``stream`` has brows of its own."""
    original = read_fap(base).stream
    if original.fps != stream.fps:
        warnings.warn(f"{base}: the base is at {original.fps:g} fps and is resampled to {stream.fps:g} fps (give "
                      f"fps={original.fps:g} to keep its rate)", BaseResampledWarning, stacklevel=3)
    recorded = fit_to_grid(original, n_frames=stream.n_frames, fps=stream.fps, source=str(base))
    if set(EYEBROW_FAPS) & set(stream.active_faps):
        # the brows are the condition's: the base's outer brows (35, 36) would not match its inner ones
        recorded = recorded.without([35, 36])
    return recorded
