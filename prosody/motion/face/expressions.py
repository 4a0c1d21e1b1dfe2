"""Facial expressions: the six MPEG-4 expressions as low-level FAP targets, blended over time and mixed with
the lips (Wu et al.'s superposition; Jia et al.'s Eq. 14).

The targets in :data:`EXPRESSIONS` (intensity 1) are ours: set from the MPEG-4 standard's description of its
six expressions (FAP 2's table: joy, sadness, anger, fear, disgust, surprise) and the facial action units of
Ekman and Friesen's prototypes that carry them, at the size of a clear, posed display rather than a faint one:
a surprised brow rises about 6 mm (200 ENS) over a jaw dropped about 10 mm (600 MNS); an angry brow falls about
8 mm at its inner end (260 ENS) and is drawn in; a sad mouth's corners fall about 4 mm (240 MNS), as far as a
smile lifts them; disgust raises the upper lip about 4 mm. Wu et al. (2006) matched its targets to JAFFE
photographs without publishing them; these are not fitted to any recording. They were set looking at four heads
and checked on 23 others by an emotion classifier trained on people's photographs (``experiments/
expression_reading.py``, in docs/evaluation.md).

Over time (:func:`expression_curves`), each segment (start, end, expression, intensity) has the dominance of
:func:`prosody.motion.face.lips.dominance` (1 inside it, decaying at :data:`ONSET_THETA` per second outside), and a
neutral face has a small constant dominance everywhere: the display reaches 87 % of its intensity 0.25 s
before the segment starts and fades the same way after it ends, and neighbouring expressions blend.

Mixing with the lips (:func:`mix_with_lips`, Jia et al.'s Eq. 14): where the viseme and the expression move a
FAP the same way, ``delta * FAP_v + (1 - delta) * FAP_e``; where they disagree, the viseme's value, so the lips
still articulate while smiling; where the visemes leave a FAP at 0 (lip corners), the expression's.
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ...errors import ConfigError
from .lips import dominance

#: The six expressions' FAP targets at intensity 1 (FAP -> value in its FAPU). Each lip corner is set on the
#: inner and the outer contour alike (12/13 with 59/60, 6/7 with 53/54): Xface copies the inner corner to the
#: outer, Greta does not, so a corner set on one contour only looks different in the two players.
EXPRESSIONS: dict[str, dict[int, float]] = {
    # AU6 + AU12: cheeks raised, lip corners up and back, lower eyelids pushed up, brows relaxed
    "joy": {12: 240, 13: 240, 59: 240, 60: 240, 6: 100, 7: 100, 53: 100, 54: 100, 41: 100, 42: 100, 21: 100,
            22: 100, 3: 40},
    # AU1 + AU4 + AU15 + AU17: inner brows up and drawn together, lids drooping, corners down, chin raised
    "sadness": {31: 120, 32: 120, 33: 20, 34: 20, 35: -60, 36: -60, 37: 50, 38: 50, 19: 150, 20: 150,
                12: -240, 13: -240, 59: -240, 60: -240, 18: 120, 5: 40, 52: 40},
    # AU4 + AU5 + AU7 + AU23/24: brows down and together, eyes staring, lower lids tense, lips pressed and narrowed
    "anger": {31: -260, 32: -260, 33: -160, 34: -160, 35: -80, 36: -80, 37: 110, 38: 110, 19: -120, 20: -120,
              21: 150, 22: 150, 4: 60, 5: 60, 51: 40, 52: 40, 6: -40, 7: -40, 53: -40, 54: -40,
              12: -60, 13: -60, 59: -60, 60: -60},
    # AU1 + AU2 + AU4 + AU5 + AU20 + AU26: brows up and together, eyes wide, lips stretched sideways and down,
    # jaw dropped
    "fear": {31: 170, 32: 170, 33: 100, 34: 100, 35: 40, 36: 40, 37: 70, 38: 70, 19: -240, 20: -240,
             6: 140, 7: 140, 53: 140, 54: 140, 12: -60, 13: -60, 59: -60, 60: -60, 3: 200, 4: -60, 5: -80,
             51: -60, 52: -80},
    # AU9 + AU10 (+ AU4, AU15): nose wrinkled, upper lip raised, cheeks up, lower lids up, brows lowered
    "disgust": {4: -240, 8: -220, 9: -220, 51: -240, 55: -220, 56: -220, 41: 120, 42: 120, 63: 100, 61: 40,
                62: 40, 31: -100, 32: -100, 33: -80, 34: -80, 37: 40, 38: 40, 21: 120, 22: 120,
                12: -80, 13: -80, 59: -80, 60: -80},
    # AU1 + AU2 + AU5 + AU26: brows high, upper lids wide open, jaw dropped
    "surprise": {31: 200, 32: 200, 33: 200, 34: 200, 35: 150, 36: 150, 19: -220, 20: -220, 3: 600, 4: -60, 5: -100,
                 51: -60, 52: -100},
}
#: Decay rate of an expression's dominance outside its segment, 1/s.
ONSET_THETA = 8.0
#: The neutral face's constant dominance.
NEUTRAL_DOMINANCE = 0.02
#: Eq. 14's weight of the viseme where both move a FAP the same way.
VISEME_WEIGHT = 0.5
#: Eyebrow FAPs (31-36) stay within this range when prosodic raises are added to an expression, ENS.
BROW_RANGE_ENS = (-300.0, 400.0)
#: Columns of a timed expression file.
EXPRESSION_FILE_COLUMNS = ("start_s", "end_s", "expression", "intensity")


@dataclass(frozen=True)
class ExpressionSegment:
    """An expression shown from ``start_s`` to ``end_s`` (None: to the end) at ``intensity`` 0..1."""

    expression: str
    intensity: float
    start_s: float = 0.0
    end_s: float | None = None

    def __post_init__(self) -> None:
        if self.expression not in EXPRESSIONS and self.expression != "neutral":
            raise ConfigError(f"unknown expression {self.expression!r}; choose from neutral, "
                              f"{', '.join(EXPRESSIONS)}")
        if not (isinstance(self.intensity, (int, float)) and 0 <= self.intensity <= 1):
            raise ConfigError(f"expression intensity must be in [0, 1], got {self.intensity!r}")
        end = math.inf if self.end_s is None else self.end_s
        if not (math.isfinite(self.start_s) and 0 <= self.start_s < end):
            raise ConfigError(f"an expression needs 0 <= start_s < end_s, got {self.start_s!r} and {self.end_s!r}",
                              parameter="start_s")


def parse_expressions(spec: str) -> list[ExpressionSegment]:
    """``NAME:INTENSITY`` for the whole recording (``joy:0.6``; ``joy`` alone is intensity 1), or the path of a
    CSV file with the columns ``start_s,end_s,expression,intensity`` (one row per segment).

    Examples
    --------
    >>> parse_expressions("surprise:0.5")
    [ExpressionSegment(expression='surprise', intensity=0.5, start_s=0.0, end_s=None)]
    """
    if os.path.exists(spec) or spec.lower().endswith(".csv"):
        return read_expression_file(spec)
    name, _, value = spec.partition(":")
    try:
        intensity = float(value) if value else 1.0
    except ValueError:
        raise ConfigError(f"expression {spec!r}: expected NAME:INTENSITY (e.g. joy:0.6) or a CSV file") from None
    return [ExpressionSegment(name.strip().lower(), intensity)]


def read_timed_rows(path: str | os.PathLike[str], columns: Sequence[str], *, what: str) -> list[tuple[int, list[str]]]:
    """The non-empty rows (line number, stripped cells) of a CSV file whose header is ``columns``; ``what``
    names the file in errors ("expression", "PAD"). Every failure is a one-line :class:`ConfigError`."""
    from audio_features.inputs import open_input

    name = str(path)
    try:
        with open_input(path, text=True, encoding="utf-8-sig", newline="", max_bytes=16 << 20) as handle:
            rows = list(csv.reader(handle))
    except FileNotFoundError:
        raise ConfigError(f"{name}: no such {what} file") from None
    except (OSError, UnicodeDecodeError, csv.Error) as error:
        raise ConfigError(f"{name}: cannot be read as CSV ({getattr(error, 'strerror', None) or error})") from None
    if not rows or tuple(cell.strip() for cell in rows[0]) != tuple(columns):
        raise ConfigError(f"{name}, line 1: expected the header {','.join(columns)}")
    found = [(line, [cell.strip() for cell in row]) for line, row in enumerate(rows[1:], start=2)
             if any(cell.strip() for cell in row)]
    if not found:
        raise ConfigError(f"{name}: no {what} rows")
    return found


def read_expression_file(path: str | os.PathLike[str]) -> list[ExpressionSegment]:
    """Timed expressions from a CSV file (columns :data:`EXPRESSION_FILE_COLUMNS`)."""
    segments = []
    for line, row in read_timed_rows(path, EXPRESSION_FILE_COLUMNS, what="expression"):
        try:
            start, end, expression, intensity = row
            segments.append(ExpressionSegment(expression.lower(), float(intensity), float(start), float(end)))
        except ValueError as error:
            raise ConfigError(f"{path}, line {line}: expected start_s,end_s,expression,intensity ({error})",
                              parameter="start_s") from None
    return segments


def expression_curves(segments: Sequence[ExpressionSegment], n_frames: int, *, fps: float) -> dict[int, np.ndarray]:
    """The expressions' FAPs over a frame grid, blended by dominance with a neutral face (see the module)."""
    return expressions_at(segments, np.arange(n_frames) / fps)


def expressions_at(segments: Sequence[ExpressionSegment], times_s: np.ndarray) -> dict[int, np.ndarray]:
    """The expressions' FAPs at any times (a live stream asks for one frame's time at a time)."""
    timed = [(segment.start_s, segment.end_s,
              {fap: segment.intensity * value for fap, value in EXPRESSIONS.get(segment.expression, {}).items()})
             for segment in segments]
    return blend_targets_at(timed, np.asarray(times_s, float))


def blend_targets(timed: Sequence[tuple[float, float | None, Mapping[int, float]]], n_frames: int, *,
                  fps: float) -> dict[int, np.ndarray]:
    """Timed FAP targets ``(start_s, end_s or None, {FAP: value})`` over a frame grid, each weighted by its
    dominance and blended with a neutral face of constant dominance (see the module)."""
    return blend_targets_at(timed, np.arange(n_frames) / fps)


def blend_targets_at(timed: Sequence[tuple[float, float | None, Mapping[int, float]]],
                     times: np.ndarray) -> dict[int, np.ndarray]:
    """:func:`blend_targets` at any times; a segment without an end lasts for ever."""
    faps = sorted({fap for _, _, targets in timed for fap in targets})
    total = np.full(times.shape, NEUTRAL_DOMINANCE)
    weighted = {fap: np.zeros(times.shape) for fap in faps}
    for start_s, end_s, targets in timed:
        weight = dominance(times, start_s=start_s, end_s=math.inf if end_s is None else end_s, alpha=1.0,
                           theta_before=ONSET_THETA, theta_after=ONSET_THETA)
        total += weight
        for fap, value in targets.items():
            weighted[fap] += weight * value
    return {fap: weighted[fap] / total for fap in faps}


def mix_with_lips(lips: Mapping[int, np.ndarray], expression: Mapping[int, np.ndarray], *,
                  delta: float = VISEME_WEIGHT) -> dict[int, np.ndarray]:
    """Jia et al.'s Eq. 14 on every FAP either moves, frame by frame.

    Examples
    --------
    >>> mixed = mix_with_lips({12: np.array([10.0, -10.0, 0.0])}, {12: np.array([30.0, 30.0, 30.0])})
    >>> mixed[12].tolist()  # same sign: averaged; opposite: the viseme's; viseme at rest: the expression's
    [20.0, -10.0, 30.0]
    """
    out = {fap: np.asarray(curve, float) for fap, curve in lips.items()}
    for fap, e in expression.items():
        if fap not in out:
            out[fap] = np.asarray(e, float)
            continue
        v = out[fap]
        same = np.sign(v) == np.sign(e)
        out[fap] = np.where(v == 0, e, np.where(same, delta * v + (1 - delta) * e, v))
    return out


def add_brow_raises(expression: Mapping[int, np.ndarray], raises: Mapping[int, np.ndarray]) -> dict[int, np.ndarray]:
    """Prosodic eyebrow raises added on top of an expression's brows, kept within :data:`BROW_RANGE_ENS`."""
    out = dict(expression)
    low, high = BROW_RANGE_ENS
    for fap, raise_ens in raises.items():
        base = out.get(fap)
        out[fap] = np.clip(raise_ens + (base if base is not None else 0.0), low, high)
    return out
