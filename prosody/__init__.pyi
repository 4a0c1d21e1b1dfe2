"""Types of the lazy facade of :mod:`prosody` (each name is imported when first asked for). Written by
``python -m scripts.facade_stub``: the functions that take settings groups have their keywords spelled
out."""

import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

from audio_features.features import Features
from prosody.evaluation.compare import Comparison
from prosody.evaluation.compare import write_comparison as write_comparison
from prosody.evaluation.preview import write_preview as write_preview
from prosody.fap.exporters import write_stream as write_stream
from prosody.fap.fapfile import read_fap as read_fap
from prosody.fap.fapfile import write_fap as write_fap
from prosody.fap.stream import FapStream as FapStream
from prosody.jobs.batch import run_batch as run_batch
from prosody.live.converter import LiveConverter as _LiveConverter
from prosody.live.session import StreamSession as StreamSession
from prosody.motion.conditions import Condition
from prosody.motion.expressions import ExpressionSegment
from prosody.motion.expressivity import Expressivity
from prosody.motion.eyebrows import BrowRule
from prosody.motion.ground_truth import RecordedMouth
from prosody.motion.head_models import HeadModel
from prosody.motion.pad import PadSegment
from prosody.motion.perlin import PerlinSettings
from prosody.motion.settings import AnalysisSettings as AnalysisSettings
from prosody.motion.settings import ChannelSettings as ChannelSettings
from prosody.motion.settings import FaceSettings as FaceSettings
from prosody.motion.settings import MotionSettings as MotionSettings

__version__: str
__all__: list[str]


def convert(
    audio: str | os.PathLike[str],
    output: str | os.PathLike[str] | None = ...,
    *,
    condition: Condition | str = ...,
    ground_truth: str | os.PathLike[str] | None = ...,
    base: str | os.PathLike[str] | None = ...,
    perlin: PerlinSettings | None = ...,
    output_format: str | None = ...,
    features: Features | None = ...,
    progress: Callable[[int, int], None] | None = ...,
    analysis: AnalysisSettings | None = ...,
    motion: MotionSettings | None = ...,
    face: FaceSettings | None = ...,
    channels: ChannelSettings | None = ...,
    fps: float = ...,
    f0_floor_hz: float = ...,
    f0_ceiling_hz: float = ...,
    model: Any = ...,
    seed: int = ...,
    eyebrow_rule: BrowRule | None = ...,
    expressivity: Expressivity | None = ...,
    lips: str | None = ...,
    transcript: str | None = ...,
    language: str | None = ...,
    mouth_model: str | os.PathLike[str] | None = ...,
    expression: str | Sequence[ExpressionSegment] | None = ...,
    pad: str | Sequence[PadSegment] | None = ...,
    pad_map: str | os.PathLike[str] | None = ...,
    gains: Mapping[str, float] | None = ...,
    disabled: Iterable[str] = ...,
) -> FapStream: ...


def compare(
    audio: str | os.PathLike[str],
    *,
    ground_truth: str | os.PathLike[str] | FapStream | None = ...,
    seeds: int = ...,
    other_head_models: Mapping[str, HeadModel | str | os.PathLike[str]] | None = ...,
    normalize: bool = ...,
    targets: Mapping[int, tuple[float, float]] | None = ...,
    conditions: Iterable[Condition | str] | None = ...,
    features: Features | None = ...,
    mouth: str | os.PathLike[str] | RecordedMouth | None = ...,
    analysis: AnalysisSettings | None = ...,
    motion: MotionSettings | None = ...,
    face: FaceSettings | None = ...,
    channels: ChannelSettings | None = ...,
    fps: float = ...,
    f0_floor_hz: float = ...,
    f0_ceiling_hz: float = ...,
    model: Any = ...,
    seed: int = ...,
    eyebrow_rule: BrowRule | None = ...,
    expressivity: Expressivity | None = ...,
    lips: str | None = ...,
    transcript: str | None = ...,
    language: str | None = ...,
    mouth_model: str | os.PathLike[str] | None = ...,
    expression: str | Sequence[ExpressionSegment] | None = ...,
    pad: str | Sequence[PadSegment] | None = ...,
    pad_map: str | os.PathLike[str] | None = ...,
    gains: Mapping[str, float] | None = ...,
    disabled: Iterable[str] = ...,
) -> Comparison: ...


class LiveConverter(_LiveConverter):
    def __init__(
        self,
        sample_rate_hz: int,
        *,
        condition: Condition | str = ...,
        lookahead_ms: float = ...,
        live_lips: bool = ...,
        expression: str | Sequence[ExpressionSegment] | None = ...,
        analysis: AnalysisSettings | None = ...,
        motion: MotionSettings | None = ...,
        channels: ChannelSettings | None = ...,
        fps: float = ...,
        f0_floor_hz: float = ...,
        f0_ceiling_hz: float = ...,
        model: Any = ...,
        seed: int = ...,
        eyebrow_rule: BrowRule | None = ...,
        expressivity: Expressivity | None = ...,
        gains: Mapping[str, float] | None = ...,
        disabled: Iterable[str] = ...,
    ) -> None: ...
