"""Comparing the four conditions on one recording (SPEC section 6): streams, metrics, plots and a report.

:func:`compare` computes; :func:`write_comparison` writes the .fap files, ``metrics.json`` (written last, so
its presence marks a complete output folder), the plots and the Markdown report.
"""

from __future__ import annotations

import json
import os
import warnings
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from audio_features import Features, extract_features
from audio_features._atomic import atomic_write

from .conditions import CONDITION_ORDER, Condition, MissingMotionWarning, condition_stream
from .errors import ConfigError
from .eyebrows import EyebrowRaises, EyebrowRule, eyebrow_raises
from .fap_table import HEAD_FAPS
from .ground_truth import fit_to_grid, read_motion
from .head import ArxHeadModel
from .metrics import (
    fap_statistics,
    first_canonical_correlation,
    head_matrix,
    normalization_targets,
    normalize_stream,
)
from .stream import FapStream

#: Version of the metrics.json layout.
METRICS_VERSION = 1
#: Conditions scaled by ``normalize`` (NO_PROSODY stays still: SPEC section 6).
NORMALIZED_CONDITIONS = (Condition.RANDOM, Condition.SPEECH_DRIVEN, Condition.GROUND_TRUTH)


@dataclass(frozen=True)
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
        The content of ``metrics.json`` (see :func:`comparison_metrics`).
    """

    source: str
    features: Features
    eyebrows: EyebrowRaises
    streams: dict[Condition, FapStream]
    metrics: dict = field(repr=False)

    @property
    def ground_truth(self) -> FapStream | None:
        return self.streams.get(Condition.GROUND_TRUTH)


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
    model: ArxHeadModel | str | os.PathLike[str] | None = None,
    seed: int = 0,
    normalize: bool = False,
    targets: Mapping[int, tuple[float, float]] | None = None,
    conditions: Iterable[Condition | str] | None = None,
    eyebrow_rule: EyebrowRule | None = None,
    fps: float = 30.0,
    f0_floor_hz: float = 75.0,
    f0_ceiling_hz: float = 500.0,
    features: Features | None = None,
) -> Comparison:
    """Compute every condition for a recording and compare them.

    Parameters
    ----------
    audio : path
        Speech recording.
    ground_truth : path or FapStream, optional
        Recorded motion (``<clip>.head.csv`` or ``.fap``); enables GROUND_TRUTH and the agreement metrics.
    model : ArxHeadModel or path, optional
        Head model for SPEECH_DRIVEN (the shipped default when omitted).
    seed : int
        Seed of the RANDOM condition.
    normalize : bool
        Scale and offset the RANDOM, SPEECH_DRIVEN and GROUND_TRUTH prosody FAPs to one mean and standard
        deviation per FAP: the ground truth's where it has the FAP, else ``targets``, else the average of the
        conditions' own (the thesis's second experiment).
    targets : mapping FAP -> (mean, std), optional
        Normalisation targets in FAP units for FAPs the ground truth lacks (or without ground truth).
    conditions : iterable, optional
        Conditions to compute (default: all four, GROUND_TRUTH only with ``ground_truth``).
    eyebrow_rule : EyebrowRule, optional
    fps, f0_floor_hz, f0_ceiling_hz : float
        Analysis settings (see :func:`audio_features.extract_features`).
    features : Features, optional
        Already extracted features of ``audio``.

    Returns
    -------
    Comparison
    """
    wanted = [c if isinstance(c, Condition) else Condition.parse(c) for c in (conditions or CONDITION_ORDER)]
    if ground_truth is None:
        if conditions is not None and Condition.GROUND_TRUTH in wanted:
            raise ConfigError("the GROUND_TRUTH condition needs recorded motion (--ground-truth FILE)")
        wanted = [c for c in wanted if c is not Condition.GROUND_TRUTH]
    if features is None:
        features = extract_features(audio, fps=fps, f0_floor_hz=f0_floor_hz, f0_ceiling_hz=f0_ceiling_hz)
    if model is None and Condition.SPEECH_DRIVEN in wanted:
        from .head import default_model

        model = default_model()
    elif model is not None and not isinstance(model, ArxHeadModel):
        model = ArxHeadModel.load(model)
    assert model is None or isinstance(model, ArxHeadModel)
    truth = None
    if ground_truth is not None:
        recorded = ground_truth if isinstance(ground_truth, FapStream) else read_motion(ground_truth)
        truth = fit_to_grid(recorded, n_frames=features.n_frames, fps=features.fps, source=str(ground_truth))
    rule = eyebrow_rule or EyebrowRule()
    eyebrows = eyebrow_raises(features, rule)
    stem = Path(str(audio)).stem
    streams: dict[Condition, FapStream] = {}
    for condition in CONDITION_ORDER:
        if condition not in wanted:
            continue
        with warnings.catch_warnings():
            # the report says which FAPs the recording lacks; no warning per condition
            warnings.simplefilter("ignore", MissingMotionWarning)
            streams[condition] = condition_stream(condition, features, seed=seed, model=model, ground_truth=truth,
                                                  eyebrows=eyebrows, name=f"{stem}_{condition.value.lower()}")
    if normalize:
        reference = streams.get(Condition.GROUND_TRUTH)
        scaled = {c: s for c, s in streams.items() if c in NORMALIZED_CONDITIONS}
        chosen = normalization_targets(scaled, reference=reference, given=targets)
        streams = {c: normalize_stream(s, chosen) if c in NORMALIZED_CONDITIONS else s for c, s in streams.items()}
    metrics = {
        "version": METRICS_VERSION,
        "source": str(audio),
        "ground_truth": None if ground_truth is None or isinstance(ground_truth, FapStream) else str(ground_truth),
        "frames": features.n_frames,
        "fps": features.fps,
        "duration_s": features.duration_s,
        "normalized": bool(normalize),
        "eyebrow_threshold_hz": eyebrows.f0_threshold_hz,
        "energy_threshold_db": eyebrows.energy_threshold_db,
        "eyebrow_events": [list(event) for event in eyebrows.events],
        "seed": seed,
        # agreement on a recording the model was trained on is not a held-out figure
        "model_trained_on_this_recording": (model is not None and
                                            stem in {clip.name for clip in model.training_}),
        **comparison_metrics(streams, features),
    }
    return Comparison(str(audio), features, eyebrows, streams, metrics)


def condition_file_name(condition: Condition) -> str:
    """File name of a condition's stream inside an output folder, e.g. ``speech_driven.fap``."""
    return f"{condition.value.lower()}.fap"


def write_comparison(comparison: Comparison, outdir: str | os.PathLike[str], *, plots: bool = True,
                     report: bool = True, extra: Mapping[str, object] | None = None) -> list[Path]:
    """Write the condition streams (.fap), the plots (PNG), the report (Markdown) and ``metrics.json``.

    ``metrics.json`` is written last: a folder holding it is complete. Every file is written atomically.

    Returns
    -------
    list of Path
        The files written.
    """
    from .fapfile import write_fap

    folder = Path(outdir)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for condition, stream in comparison.streams.items():
        path = folder / condition_file_name(condition)
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
    return written

