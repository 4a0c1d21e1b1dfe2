"""One call per job: audio in, FAP stream (and file) out. The CLI is a thin shell over these."""

from __future__ import annotations

import os
from pathlib import Path

from audio_features import Features, extract_features

from .conditions import Condition, condition_stream
from .eyebrows import EyebrowRule
from .fapfile import read_fap
from .ground_truth import fit_to_grid, read_motion
from .head import ArxHeadModel
from .perlin import PerlinSettings
from .stream import FapStream


def load_ground_truth(path: str | os.PathLike[str], features: Features) -> FapStream:
    """Recorded motion (.head.csv or .fap) on the features' grid."""
    return fit_to_grid(read_motion(path), n_frames=features.n_frames, fps=features.fps, source=str(path))


def convert(
    audio: str | os.PathLike[str],
    output: str | os.PathLike[str] | None = None,
    *,
    condition: Condition | str = Condition.SPEECH_DRIVEN,
    ground_truth: str | os.PathLike[str] | None = None,
    model: ArxHeadModel | str | os.PathLike[str] | None = None,
    base: str | os.PathLike[str] | None = None,
    seed: int = 0,
    fps: float = 30.0,
    f0_floor_hz: float = 75.0,
    f0_ceiling_hz: float = 500.0,
    eyebrow_rule: EyebrowRule | None = None,
    perlin: PerlinSettings | None = None,
    output_format: str | None = None,
    features: Features | None = None,
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
    model : ArxHeadModel or path, optional
        Head model for ``speech``; the shipped default when omitted.
    base : path, optional
        A .fap recording whose other FAPs (lips, eyes) are carried into the output.
    seed : int
        Seed of the ``random`` condition.
    fps : float > 0
        Frame rate of the output.
    features : Features, optional
        Already extracted features of ``audio`` (skips the analysis).

    Returns
    -------
    FapStream
    """
    chosen = condition if isinstance(condition, Condition) else Condition.parse(condition)
    if features is None:
        features = extract_features(audio, fps=fps, f0_floor_hz=f0_floor_hz, f0_ceiling_hz=f0_ceiling_hz)
    if model is not None and not isinstance(model, ArxHeadModel):
        model = ArxHeadModel.load(model)
    truth = load_ground_truth(ground_truth, features) if ground_truth is not None else None
    name = Path(output).stem if output is not None else Path(str(audio)).stem
    stream = condition_stream(chosen, features, seed=seed, model=model, ground_truth=truth,
                              eyebrow_rule=eyebrow_rule, perlin=perlin, name=name)
    if base is not None:
        stream = stream.merged_over(read_fap(base).stream)
    if output is not None:
        from .exporters import write_stream

        write_stream(stream, output, output_format)
    return stream
