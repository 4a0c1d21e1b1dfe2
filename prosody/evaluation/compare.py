"""Comparing the four conditions on one recording (docs/evaluation.md): streams, metrics, plots and a report.

:func:`compare` computes; :func:`write_comparison` writes the .fap files, ``metrics.json`` (written last, so
its presence marks a complete output folder), the plots and the Markdown report.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import warnings
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from audio_features import Features, extract_features
from audio_features.atomic import atomic_write

from ..errors import ConfigError
from ..fap.recorded import RecordedMouth, fit_to_grid, mouth_beside, read_motion, read_mouth_csv
from ..fap.stream import FapStream
from ..fap.table import HEAD_FAPS
from ..measures import (
    average_brow_metrics,
    average_head_metrics,
    average_mouth_metrics,
    brow_metrics,
    empty_brow_metrics,
    empty_head_metrics,
    empty_mouth_metrics,
    fap_statistics,
    first_canonical_correlation,
    head_matrix,
    head_measured,
    head_metrics,
    mouth_metrics,
    normalization_targets,
    normalize_stream,
)
from ..motion.conditions import (
    CONDITION_ORDER,
    Condition,
    MissingMotionWarning,
    condition_stream,
    expressive,
    head_motion,
)
from ..motion.controls import shift_offsets, shifted_features
from ..motion.expressivity import Expressivity
from ..motion.eyebrows import BrowRule, EyebrowRaises, NoRaiseWarning, brow_raises, warn_if_no_raise
from ..motion.face.layer import stream_mouth
from ..motion.heads.models import HeadModel, is_stochastic, resolve_head_model, rest_pose
from ..motion.settings import (
    AnalysisSettings,
    ChannelSettings,
    FaceSettings,
    MotionSettings,
    SettingsFields,
    make_face,
    settings_groups,
)
from ..validate import valid_seeds
from .metrics import METRICS_VERSION, Metrics

if TYPE_CHECKING:
    from typing_extensions import Unpack

    from .preview import Face

#: Seeds over which the measures of a stochastic condition (RANDOM, the prosodic SPEECH_DRIVEN head) are
#: averaged: seed, seed + 1, ... (the written streams use the first).
SUMMARY_SEEDS = 10
#: Conditions scaled by ``normalize`` (NO_PROSODY stays still: docs/evaluation.md).
NORMALIZED_CONDITIONS = (Condition.RANDOM, Condition.SPEECH_DRIVEN, Condition.GROUND_TRUTH)


# arrays inside: equality is identity (numpy's == is elementwise), so it stays hashable
@dataclass(frozen=True, eq=False)
class Comparison:
    """The conditions of one recording and how they compare.

    Attributes
    ----------
    source : str
        The audio file.
    features : Features
    eyebrows : EyebrowRaises
        The eyebrow rule's result (its events are drawn in the plots).
    streams : dict
        Condition -> FapStream of the prosody FAPs, in :data:`CONDITION_ORDER`; GROUND_TRUTH only when
        recorded motion was given.
    metrics : dict
        The content of ``metrics.json`` (see :func:`comparison_metrics`); :attr:`measures` reads it as types.
    other_models : dict
        Label -> the speech-driven stream with another head model's head (``other_head_models``; its first
        seed), for the files and the video.
    """

    source: str
    features: Features
    eyebrows: EyebrowRaises
    streams: dict[Condition, FapStream]
    metrics: dict = field(repr=False)
    other_models: dict[str, FapStream] = field(default_factory=dict, repr=False)

    @property
    def ground_truth(self) -> FapStream | None:
        return self.streams.get(Condition.GROUND_TRUTH)

    @property
    def measures(self) -> Metrics:
        """:attr:`metrics` as types (:class:`prosody.evaluation.metrics.Metrics`)."""
        return Metrics.from_json(self.metrics)


def brow_curve(stream: FapStream) -> np.ndarray | None:
    """The inner-brow raise of a stream (mean of FAP 31 and 32 where both are active, else FAP 31), ENS;
    None if the stream has no inner brow throughout."""
    left, right = stream.mask[:, 30], stream.mask[:, 31]
    if not left.all():
        return None
    if right.all():
        return (stream.values[:, 30] + stream.values[:, 31]) / 2
    return stream.values[:, 30].copy()


def _trained_on(head_model, audio, stem: str) -> bool:
    """Whether ``head_model`` was trained on this recording: the same audio (by SHA-256), or, for model
    files that do not record it, the same name."""
    if head_model is None:
        return False
    from ..motion.model_files import audio_digest

    clips = head_model.training_
    digests = {clip.audio_sha256 for clip in clips if clip.audio_sha256}
    if digests:
        return audio_digest(audio if isinstance(audio, (str, os.PathLike)) else None) in digests
    return stem in {clip.name for clip in clips}


def _measure(runs: list[FapStream], truth_head: np.ndarray | None, truth_brow: np.ndarray | None, *,
             fps: float, measured: np.ndarray | None = None) -> tuple[dict, dict]:
    """Head and brow measures of several runs of one condition against the recording, averaged (head
    measures on the ``measured`` frames only)."""
    head = (average_head_metrics([head_metrics(head_matrix(run), truth_head, fps=fps, measured=measured)
                                  for run in runs])
            if truth_head is not None else empty_head_metrics())
    brows = [brow_curve(run) for run in runs]
    brow = (average_brow_metrics([brow_metrics(curve, truth_brow, fps=fps) for curve in brows if curve is not None])
            if truth_brow is not None else empty_brow_metrics())
    return head, brow


def _mouth_measures(streams: Mapping[Condition, FapStream], mouth, ground_truth, audio,
                    features: Features) -> tuple[dict, dict]:
    """Mouth measures of each condition with lips against a tracked mouth, and of the mismatched-audio
    control: the speech-driven lips shifted in time by the head control's offsets, at the speech's lag."""
    if mouth is None:
        for beside in (ground_truth, audio):
            found = mouth_beside(beside) if isinstance(beside, (str, os.PathLike)) else None
            if found is not None:
                mouth = found
                break
    blocks: dict = {"reference": None}
    if mouth is None:
        return blocks, empty_mouth_metrics()
    recorded = mouth if isinstance(mouth, RecordedMouth) else read_mouth_csv(mouth)
    blocks["reference"] = None if isinstance(mouth, RecordedMouth) else str(mouth)
    n = features.n_frames

    def on_grid(values: np.ndarray) -> np.ndarray:
        # the tracked mouth is at 30 fps from the audio's start; NaN beyond its end
        times = np.arange(n) / features.fps
        index = np.round(times * recorded.fps).astype(int)
        out = np.full(n, np.nan)
        inside = index < values.size
        out[inside] = values[index[inside]]
        return out

    opening, rounding = on_grid(recorded.lip_opening), on_grid(recorded.rounding)
    control = empty_mouth_metrics()
    for condition, stream in streams.items():
        generated = stream_mouth(stream)
        if generated is None:
            continue
        blocks[condition.value] = mouth_metrics(*generated, opening, rounding, fps=features.fps)
        if condition is Condition.SPEECH_DRIVEN:
            lag = int(round(blocks[condition.value]["lag_s"] * features.fps))
            control = average_mouth_metrics([
                mouth_metrics(np.roll(generated[0], offset), np.roll(generated[1], offset), opening, rounding,
                              fps=features.fps, lag_frames=lag)
                for offset in shift_offsets(n, fps=features.fps)])
    return blocks, control


def comparison_metrics(streams: Mapping[Condition, FapStream], features: Features) -> dict:
    """Statistics per condition and FAP, agreement with ground truth and canonical correlations.

    Returns
    -------
    dict
        ``{"conditions": {name: {"<fap>": {"mean", "std", "pearson_r", "rmse"}}}, "cca": {"head_vs_ground_truth":
        {name: r or None}, "audio_vs_head": {name: r or None}}}``. ``pearson_r`` and ``rmse`` are against the
        ground truth, None without it (or where undefined); CCA values are the first canonical correlation
        between the three head axes and the recorded head axes, and between (energy, conditioned F0) and the
        head axes.
    """
    truth = streams.get(Condition.GROUND_TRUTH)
    truth_has_head = truth is not None and all(truth.mask[:, fap - 1].all() for fap in HEAD_FAPS)
    audio = np.column_stack([features.energy.values, features.f0_conditioned.values])
    conditions, head_vs_truth, audio_vs_head = {}, {}, {}
    for condition, stream in streams.items():
        conditions[condition.value] = fap_statistics(stream, truth)
        head = head_matrix(stream)
        head_vs_truth[condition.value] = (first_canonical_correlation(head, head_matrix(truth))
                                          if truth_has_head and truth is not None else None)
        audio_vs_head[condition.value] = first_canonical_correlation(audio, head)
    return {"conditions": conditions, "cca": {"head_vs_ground_truth": head_vs_truth,
                                              "audio_vs_head": audio_vs_head}}


def compare(
    audio: str | os.PathLike[str],
    *,
    ground_truth: str | os.PathLike[str] | FapStream | None = None,
    seeds: int = SUMMARY_SEEDS,
    other_head_models: Mapping[str, HeadModel | str | os.PathLike[str]] | None = None,
    normalize: bool = False,
    targets: Mapping[int, tuple[float, float]] | None = None,
    conditions: Iterable[Condition | str] | None = None,
    features: Features | None = None,
    mouth: str | os.PathLike[str] | RecordedMouth | None = None,
    analysis: AnalysisSettings = AnalysisSettings(),
    motion: MotionSettings = MotionSettings(),
    face: FaceSettings = FaceSettings(),
    channels: ChannelSettings = ChannelSettings(),
    **fields: Unpack[SettingsFields],
) -> Comparison:
    """Compute every condition for a recording and compare them.

    Parameters
    ----------
    audio : path
        Speech recording.
    ground_truth : path or FapStream, optional
        Recorded motion (``<clip>.head.csv`` or ``.fap``); enables GROUND_TRUTH and the agreement metrics.
    seeds : int >= 1
        Number of seeds (``seed``, ``seed + 1``, ...) over which the head measures of the stochastic
        conditions and of the mismatched-audio control are averaged; the written streams use ``seed``.
    other_head_models : mapping label -> head model, shipped name or path, optional
        Head models measured beside SPEECH_DRIVEN's, with their own mismatched-audio control (for example
        ``{"arx": "arx"}``: the thesis's model next to the default); in ``metrics["other_head_models"]``.
    normalize : bool
        Scale and offset the RANDOM, SPEECH_DRIVEN and GROUND_TRUTH prosody FAPs to one mean and standard
        deviation per FAP: the ground truth's where it has the FAP, else ``targets``, else the average of the
        conditions' own (the thesis's second experiment).
    targets : mapping FAP -> (mean, std), optional
        Normalisation targets in FAP units for FAPs the ground truth lacks (or without ground truth).
    conditions : iterable, optional
        Conditions to compute (default: all four, GROUND_TRUTH only with ``ground_truth``).
    features : Features, optional
        Already extracted features of ``audio``.
    mouth : path or RecordedMouth, optional
        A video-tracked mouth (``<clip>.mouth.csv``) for the mouth measures; by default the one beside
        ``ground_truth`` or ``audio``, if any.
    analysis : AnalysisSettings, optional
        How the recording is analysed; or its fields as keywords (below).
    motion : MotionSettings, optional
        The head model, the seed, the brow rule and the expressivity controls (on the generated conditions,
        their controls and the other head models alike; recorded motion is left as it is); or its fields.
    face : FaceSettings, optional
        The lips, expression and PAD state's partial expressions given to every condition alike; or its fields.
    channels : ChannelSettings, optional
        Gains and channels left out, on the generated conditions and their controls alike (recorded motion is
        left as it is), as ``convert`` applies them; or its fields.
    **fields
        Any field of the groups above by its name, overriding that group's: ``fps``, ``f0_floor_hz``,
        ``f0_ceiling_hz``, ``workers`` (analysis); ``model``, ``seed``, ``eyebrow_rule``, ``expressivity``
        (motion); ``lips``, ``transcript``, ``language``, ``mouth_model``, ``expression``, ``pad``, ``pad_map``
        (face); ``gains``, ``disabled`` (channels). Typed by :class:`~prosody.motion.settings.SettingsFields`.

    Returns
    -------
    Comparison
    """
    analysis, motion, face, channels = settings_groups("compare", fields, analysis=analysis, motion=motion, face=face,
                                                       channels=channels)
    channels.check_leaves_output(lips=face.lips is not None, face_layer=bool(face.expression or face.pad))
    wanted = [c if isinstance(c, Condition) else Condition.parse(c) for c in (conditions or CONDITION_ORDER)]
    if ground_truth is None:
        if conditions is not None and Condition.GROUND_TRUTH in wanted:
            raise ConfigError("the GROUND_TRUTH condition needs recorded motion (ground_truth=FILE)",
                              parameter="ground_truth")
        wanted = [c for c in wanted if c is not Condition.GROUND_TRUTH]
    if features is None:
        features = extract_features(audio, **analysis.as_keywords(), workers=analysis.workers)
    head_model = resolve_head_model(motion.model) if Condition.SPEECH_DRIVEN in wanted else None
    seed, seeds = motion.seed, valid_seeds(seeds)
    eyebrow_rule, expressivity = motion.eyebrow_rule, motion.expressivity
    truth = None
    if ground_truth is not None:
        recorded = ground_truth if isinstance(ground_truth, FapStream) else read_motion(ground_truth)
        truth = fit_to_grid(recorded, n_frames=features.n_frames, fps=features.fps, source=str(ground_truth))
    eyebrows = brow_raises(features, eyebrow_rule)
    if Condition.SPEECH_DRIVEN in wanted:
        warn_if_no_raise(eyebrows)
    # the same lips and expression in every condition: the comparison is about prosody
    layer = make_face(audio, features, face, channels)
    setup = _Setup(features, eyebrows, eyebrow_rule, head_model, truth, Path(str(audio)).stem, layer, expressivity,
                   seed, seeds, normalize, channels)
    streams = setup.generate(wanted, targets)
    head_blocks, brow_blocks, control, brow_control = setup.measure_conditions(streams)
    metrics = {**setup.recording_metrics(audio, ground_truth), **comparison_metrics(streams, features)}
    mouth_blocks, mouth_control = _mouth_measures(streams, mouth, ground_truth, audio, features)
    metrics["mouth_reference"] = mouth_blocks.pop("reference")
    for name, block in metrics["conditions"].items():
        block["head"] = head_blocks.get(name, empty_head_metrics())
        block["brows"] = brow_blocks.get(name, empty_brow_metrics())
        block["mouth"] = mouth_blocks.get(name, empty_mouth_metrics())
    metrics["controls"] = {"mismatched_audio": control, "mismatched_audio_brows": brow_control,
                           "mismatched_audio_mouth": mouth_control}
    others, other_streams = setup.other_head_models(streams, other_head_models or {})
    if others:
        metrics["other_head_models"] = others
    return Comparison(str(audio), features, eyebrows, streams, metrics, other_streams)


@dataclass
class _Setup:
    """What the parts of one comparison share: the recording's analysis, the brows, the head model, the
    recorded motion, the face laid over every condition and the seeds."""

    features: Features
    eyebrows: EyebrowRaises
    rule: BrowRule | None
    head_model: HeadModel | None
    truth: FapStream | None
    stem: str
    face: object
    expressivity: Expressivity | None
    seed: int
    seeds: int
    normalize: bool
    channels: ChannelSettings | None = None
    targets: dict[int, tuple[float, float]] = field(default_factory=dict)

    def recording_metrics(self, audio: str | os.PathLike[str], ground_truth: object) -> dict:
        """The head of ``metrics.json``: what was compared, and how."""
        features, eyebrows, head_model = self.features, self.eyebrows, self.head_model
        return {
            "version": METRICS_VERSION,
            "source": str(audio),
            "ground_truth": None if ground_truth is None or isinstance(ground_truth, FapStream) else str(ground_truth),
            "frames": features.n_frames,
            "fps": features.fps,
            "duration_s": features.duration_s,
            "normalized": bool(self.normalize),
            "eyebrow_rule": eyebrows.rule,
            # infinite where the recording has no voice to set them by: null in JSON
            "eyebrow_threshold_hz": eyebrows.f0_threshold_hz if np.isfinite(eyebrows.f0_threshold_hz) else None,
            "energy_threshold_db": eyebrows.energy_threshold_db if np.isfinite(eyebrows.energy_threshold_db) else None,
            "eyebrow_events": [list(event) for event in eyebrows.events],
            "seed": self.seed,
            "seeds": self.seeds,
            "head_model": None if head_model is None else head_model.kind,
            # agreement on a recording the model was trained on is not a held-out figure
            "model_trained_on_this_recording": _trained_on(head_model, audio, self.stem),
        }

    def make(self, condition: Condition, run_seed: int, source: Features | None = None) -> FapStream:
        """One condition's stream (on ``source``: another recording's analysis, for the controls)."""
        source = self.features if source is None else source
        with warnings.catch_warnings():
            # the report says which FAPs the recording lacks; no warning per condition
            warnings.simplefilter("ignore", MissingMotionWarning)
            warnings.simplefilter("ignore", NoRaiseWarning)  # said once, not per control run
            stream = condition_stream(condition, source, seed=run_seed, model=self.head_model, ground_truth=self.truth,
                                      eyebrows=self.eyebrows if source is self.features else None,
                                      eyebrow_rule=self.rule, name=f"{self.stem}_{condition.value.lower()}",
                                      expressivity=self.expressivity)
        stream = self.face.over(stream) if self.face is not None else stream  # type: ignore[attr-defined]
        if self.channels is not None and condition is not Condition.GROUND_TRUTH:
            rest = rest_pose(self.head_model) if condition is Condition.SPEECH_DRIVEN and self.head_model else None
            stream = self.channels.applied(stream, rest=rest)
        return stream

    def finished(self, condition: Condition, stream: FapStream) -> FapStream:
        """``stream`` normalised as the comparison's conditions are."""
        if self.normalize and condition in NORMALIZED_CONDITIONS:
            return normalize_stream(stream, self.targets)
        return stream

    def generate(self, wanted: list[Condition], targets: Mapping[int, tuple[float, float]] | None) \
            -> dict[Condition, FapStream]:
        """The wanted conditions' streams at the comparison's seed, normalised if asked."""
        streams = {condition: self.make(condition, self.seed) for condition in CONDITION_ORDER if condition in wanted}
        if self.normalize:
            reference = streams.get(Condition.GROUND_TRUTH)
            scaled = {c: s for c, s in streams.items() if c in NORMALIZED_CONDITIONS}
            self.targets = normalization_targets(scaled, reference=reference, given=targets)
            streams = {c: self.finished(c, s) for c, s in streams.items()}
        return streams

    @property
    def stochastic(self) -> set[Condition]:
        """Conditions whose measures are averaged over seeds."""
        speech = self.head_model is not None and is_stochastic(self.head_model)
        return {Condition.RANDOM} | ({Condition.SPEECH_DRIVEN} if speech else set())

    def truth_curves(self) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None]:
        """(head matrix, frames the tracker measured, brow curve) of the recorded motion; frames a tracker lost
        are bridged in the head matrix and left out of the head measures."""
        if self.truth is None:
            return None, None, None
        measured = head_measured(self.truth)
        head = head_matrix(self.truth) if measured is not None and measured.any() else None
        return head, measured, brow_curve(self.truth)

    def measure_conditions(self, streams: Mapping[Condition, FapStream]) -> tuple[dict, dict, dict, dict]:
        """Head and brow measures of every condition against the recording (stochastic conditions over several
        seeds), and of the same generator driven by this recording's audio shifted in time (the
        mismatched-audio control): (head blocks, brow blocks, head control, brow control)."""
        truth_head, measured, truth_brow = self.truth_curves()
        head_blocks: dict[str, dict] = {}
        brow_blocks: dict[str, dict] = {}
        control, brow_control = empty_head_metrics(), empty_brow_metrics()
        if truth_head is None and truth_brow is None:
            return head_blocks, brow_blocks, control, brow_control
        fps, stochastic = self.features.fps, self.stochastic
        for condition, stream in streams.items():
            runs = [stream] + ([self.finished(condition, self.make(condition, self.seed + k))
                                for k in range(1, self.seeds)] if condition in stochastic else [])
            head_blocks[condition.value], brow_blocks[condition.value] = _measure(
                runs, truth_head, truth_brow, fps=fps, measured=measured)
        if Condition.SPEECH_DRIVEN in streams:
            speech = Condition.SPEECH_DRIVEN
            run_seeds = range(self.seed, self.seed + self.seeds) if speech in stochastic else [self.seed]
            runs = [self.finished(speech, self.make(speech, run_seed, shifted_features(self.features, offset)))
                    for run_seed in run_seeds for offset in shift_offsets(self.features.n_frames, fps=fps)]
            control, brow_control = _measure(runs, truth_head, truth_brow, fps=fps, measured=measured)
        return head_blocks, brow_blocks, control, brow_control

    def other_head_models(self, streams: Mapping[Condition, FapStream],
                          models: Mapping[str, HeadModel | str | os.PathLike[str]]) \
            -> tuple[dict[str, dict], dict[str, FapStream]]:
        """Head models measured beside the speech-driven one (e.g. the thesis's ARX next to the default), each
        with its own mismatched-audio control, and their streams (the speech-driven stream with their head)."""
        truth_head, measured, _ = self.truth_curves()
        features = self.features
        others: dict[str, dict] = {}
        other_streams: dict[str, FapStream] = {}
        for label, other in models.items():
            other_model = resolve_head_model(other)
            run_seeds = list(range(self.seed, self.seed + self.seeds)) if is_stochastic(other_model) else [self.seed]

            def head_of(source: Features, run_seed: int, chosen: HeadModel = other_model) -> np.ndarray:
                curves = expressive(head_motion(chosen, source, seed=run_seed), fps=source.fps,
                                    expressivity=self.expressivity, rest=rest_pose(chosen))
                stream = FapStream.from_curves(curves, fps=source.fps)
                return head_matrix(self.finished(Condition.SPEECH_DRIVEN, stream))

            entry: dict = {"kind": other_model.kind, "head": empty_head_metrics(),
                           "mismatched_audio": empty_head_metrics()}
            if truth_head is not None:
                entry["head"] = average_head_metrics([
                    head_metrics(head_of(features, s), truth_head, fps=features.fps, measured=measured)
                    for s in run_seeds])
                entry["mismatched_audio"] = average_head_metrics([
                    head_metrics(head_of(shifted_features(features, offset), s), truth_head, fps=features.fps,
                                 measured=measured)
                    for s in run_seeds for offset in shift_offsets(features.n_frames, fps=features.fps)])
            others[str(label)] = entry
            if Condition.SPEECH_DRIVEN in streams:
                head = head_of(features, run_seeds[0])
                other_streams[str(label)] = streams[Condition.SPEECH_DRIVEN].with_curves(
                    {fap: head[:, axis] for axis, fap in enumerate(HEAD_FAPS)})
        return others, other_streams


def other_model_name(label: str) -> str:
    """How another head model is named in files and video panels: a shipped name as it is, a model file by
    its name without the ending."""
    return Path(label).name.removesuffix(".json")


def other_model_file_name(label: str) -> str:
    """File name of another head model's speech-driven stream in an output folder, e.g.
    ``speech_driven.arx.fap``."""
    stem = other_model_name(label)
    return f"speech_driven.{re.sub(r'[^A-Za-z0-9_-]+', '_', stem) or 'model'}.fap"


def condition_file_name(condition: Condition) -> str:
    """File name of a condition's stream inside an output folder, e.g. ``speech_driven.fap``."""
    return f"{condition.value.lower()}.fap"


#: File name of the side-by-side video in a comparison folder.
VIDEO_FILE = "conditions.mp4"
#: Files a comparison folder may hold; writing it again removes those the new settings no longer write, so
#: an earlier run's video or plots never stand beside newer results.
OUTPUT_NAMES = (*(condition_file_name(c) for c in CONDITION_ORDER), "features.png", "head.png", "report.md",
                VIDEO_FILE, "metrics.json")


def write_comparison(comparison: Comparison, outdir: str | os.PathLike[str], *, plots: bool = True,
                     report: bool = True, extra: Mapping[str, object] | None = None, video: bool = False,
                     exaggerate: float = 1.0, progress: Callable[[int, int], None] | None = None,
                     face: Face = "head") -> list[Path]:
    """Write the condition streams (.fap), the plots (PNG), the report (Markdown) and ``metrics.json``; with
    ``video``, also ``conditions.mp4``: the conditions' faces side by side, labelled, with the recording's
    audio (``exaggerate`` multiplies the drawn motion; ``progress`` as in
    :func:`prosody.evaluation.preview.write_preview`).

    ``metrics.json`` is written last: a folder holding it is complete. Every file is written atomically.

    Parameters
    ----------
    comparison : Comparison
        What :func:`compare` computed.
    outdir : path-like
        The folder (created if missing).
    plots, report : bool
        Draw the figures (PNG) and write ``report.md``.
    extra : mapping, optional
        More entries for ``metrics.json`` (a batch's options, say).
    video : bool
        Also draw ``conditions.mp4``.
    exaggerate : float
        Multiplies the drawn motion of the video.
    progress : callable, optional
        Called as ``progress(frames_done, frames_total)`` while the video is drawn.
    face : {"head", "drawn"}, PhotoHead or path of a photo
        The face of the video's panels (see :func:`prosody.evaluation.preview.render_frames`).

    Returns
    -------
    list of Path
        The files written.
    """
    from ..fap.fapfile import write_fap

    folder = Path(outdir)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for condition, stream in comparison.streams.items():
        path = folder / condition_file_name(condition)
        write_fap(stream, path, name=stream.name)
        written.append(path)
    for label, stream in comparison.other_models.items():
        path = folder / other_model_file_name(label)
        write_fap(stream, path, name=stream.name)
        written.append(path)
    figures: dict[str, str] = {}
    if plots:
        from .plots import plot_features, plot_head

        for key, function in (("features", plot_features), ("head", plot_head)):
            path = folder / f"{key}.png"
            function(comparison, path)
            figures[key] = path.name
            written.append(path)
    if video:
        from .preview import write_side_by_side

        path = folder / VIDEO_FILE
        panels = {condition.value: stream for condition, stream in comparison.streams.items()}
        panels.update({f"SPEECH_DRIVEN ({other_model_name(label)})": stream
                       for label, stream in comparison.other_models.items()})
        write_side_by_side(panels, path, audio=comparison.source, exaggerate=exaggerate, progress=progress,
                           face=face)
        written.append(path)
    if report:
        from .report import comparison_markdown

        path = folder / "report.md"
        with atomic_write(path, newline="\n") as handle:
            handle.write(comparison_markdown(comparison, figures=figures))
        written.append(path)
    path = folder / "metrics.json"
    payload = dict(comparison.metrics)
    if extra:
        payload.update(extra)
    with atomic_write(path, newline="\n") as handle:
        json.dump(payload, handle, indent=1, allow_nan=False)
        handle.write("\n")
    written.append(path)
    kept = {path.name for path in written}
    stale_others = [p.name for p in folder.glob("speech_driven.*.fap")]
    for name in (*OUTPUT_NAMES, *stale_others):
        if name not in kept:
            with contextlib.suppress(FileNotFoundError):
                (folder / name).unlink()
    return written

