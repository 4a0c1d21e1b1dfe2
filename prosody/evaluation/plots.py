"""Figures of a comparison (PNG, drawn with matplotlib's non-interactive Agg backend).

- ``plot_features``: F0 (raw and conditioned, with the eyebrow threshold), energy (with its threshold) and
  the eyebrow displacement, with every raise shaded, on one time axis;
- ``plot_head``: head pitch, yaw and roll in degrees, each condition against the ground truth.
"""

from __future__ import annotations

import io
import os
from typing import TYPE_CHECKING

import numpy as np

from audio_features.atomic import atomic_write

from ..fap.table import BY_NUMBER, HEAD_FAPS, RADIANS_PER_AU

if TYPE_CHECKING:
    from .compare import Comparison

#: One colour per condition, the same in every figure.
CONDITION_COLOURS = {"NO_PROSODY": "0.6", "RANDOM": "tab:orange", "SPEECH_DRIVEN": "tab:blue",
                     "GROUND_TRUTH": "black"}


def new_figure(**options):
    """A figure drawn by matplotlib's Agg canvas directly: pyplot and its backend, which a caller (a notebook)
    may have chosen, are left alone."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(**options)
    FigureCanvasAgg(figure)
    return figure


def save_figure(figure, path: str | os.PathLike[str], *, tight: bool = False) -> None:
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=110, **({"bbox_inches": "tight", "pad_inches": 0.15} if tight else {}))
    with atomic_write(path, mode="wb") as handle:
        handle.write(buffer.getvalue())


def _shade_raises(axis, comparison: Comparison) -> None:
    fps = comparison.features.fps
    for onset, release in comparison.eyebrows.events:
        axis.axvspan(onset / fps, release / fps, color="tab:green", alpha=0.12, linewidth=0)


def plot_features(comparison: Comparison, path: str | os.PathLike[str]) -> None:
    """F0, energy and eyebrow raises of the recording, with the rule's thresholds, as a PNG."""
    features = comparison.features
    times = features.f0.times_s
    figure = new_figure(figsize=(10, 7))
    f0_axis, energy_axis, brow_axis = figure.subplots(3, 1, sharex=True)
    f0_axis.plot(times, features.f0_conditioned.values, color="tab:blue", linewidth=1.2,
                 label="conditioned F0")
    f0_axis.plot(times, features.f0.values, ".", color="black", markersize=2.5, label="Praat F0 (voiced)")
    raises = comparison.eyebrows
    if np.isfinite(raises.f0_threshold_hz):
        f0_axis.axhline(raises.f0_threshold_hz, color="tab:red", linestyle="--", linewidth=1,
                        label=f"raise threshold {raises.f0_threshold_hz:.0f} Hz")
    f0_axis.set_ylabel("F0 (Hz)")
    f0_axis.legend(loc="upper right", fontsize=8)
    energy_axis.plot(times, features.energy.values, color="tab:purple", linewidth=1)
    if np.isfinite(raises.energy_threshold_db):
        what = "loudness a raise needs" if raises.rule == "accent" else "hold threshold"
        energy_axis.axhline(raises.energy_threshold_db, color="tab:red", linestyle="--",
                            linewidth=1, label=f"{what} {raises.energy_threshold_db:.0f} dB")
    energy_axis.set_ylabel("energy (dB)")
    energy_axis.legend(loc="upper right", fontsize=8)
    for condition, stream in comparison.streams.items():
        if stream.mask[:, 30].any():
            brow_axis.plot(times, stream.curve(31), color=CONDITION_COLOURS[condition.value], linewidth=1,
                           label=condition.value)
    brow_axis.set_ylabel("inner brow, FAP 31 (ENS)")
    brow_axis.set_xlabel("time (s)")
    brow_axis.legend(loc="upper right", fontsize=8)
    for axis in (f0_axis, energy_axis, brow_axis):
        _shade_raises(axis, comparison)
        axis.grid(alpha=0.3)
    f0_axis.set_title(f"{os.path.basename(comparison.source)}: acoustics and eyebrow raises (shaded)")
    figure.tight_layout()
    save_figure(figure, path)


def plot_head(comparison: Comparison, path: str | os.PathLike[str]) -> None:
    """Head pitch, yaw and roll (degrees) of every condition, ground truth in black, as a PNG."""
    times = comparison.features.f0.times_s
    figure = new_figure(figsize=(10, 7))
    axes = figure.subplots(3, 1, sharex=True)
    for axis, fap in zip(axes, HEAD_FAPS, strict=False):
        for condition, stream in comparison.streams.items():
            if condition.value == "NO_PROSODY" or not stream.mask[:, fap - 1].any():
                continue
            degrees = np.degrees(stream.curve(fap) * RADIANS_PER_AU)
            axis.plot(times, degrees, color=CONDITION_COLOURS[condition.value],
                      linewidth=1.6 if condition.value == "GROUND_TRUTH" else 1.0, label=condition.value)
        axis.axhline(0, color=CONDITION_COLOURS["NO_PROSODY"], linewidth=0.8)
        info = BY_NUMBER[fap]
        axis.set_ylabel(f"{info.name}\n(deg, + {info.positive_motion})", fontsize=9)
        axis.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8, ncol=3)
    axes[-1].set_xlabel("time (s)")
    normalised = " (normalised)" if comparison.metrics.get("normalized") else ""
    axes[0].set_title(f"{os.path.basename(comparison.source)}: head rotation per condition{normalised}")
    figure.tight_layout()
    save_figure(figure, path)
