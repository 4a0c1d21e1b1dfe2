"""Calls a type checker must accept or refuse, checked by ``make lint`` (mypy with ``warn_unused_ignores``): each
refused call carries the ignore of the error mypy must report, so an error no longer seen fails the lint as an
unused ignore. Never run; only read by mypy."""

from __future__ import annotations

from prosody import AnalysisSettings, FaceSettings, LiveConverter, compare, convert
from prosody.jobs.pipeline import apply_controls


def accepted() -> None:
    convert("a.wav", fps=25.0, lips="acoustic", seed=3, gains={"pitch": 0.5}, disabled=("roll",))
    convert("a.wav", analysis=AnalysisSettings(fps=25.0), face=FaceSettings(lips="combined"), fps=30.0)
    compare("a.wav", model="arx", transcript="hello")
    LiveConverter(16000, fps=30.0, seed=1, gains={"brows": 2.0})


def refused() -> None:
    convert("a.wav", fpss=25)  # type: ignore[call-arg]
    convert("a.wav", fps="fast")  # type: ignore[arg-type]
    compare("a.wav", lips=3)  # type: ignore[arg-type]
    LiveConverter(16000, lips="visemes")  # type: ignore[call-arg]
    apply_controls(convert("a.wav"), seed=2)  # type: ignore[call-arg]
