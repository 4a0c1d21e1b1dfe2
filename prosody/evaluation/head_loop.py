"""The head's closed loop: known motion -> ``prosody preview`` -> ``prosody track`` -> the motion measured back.

A FAP stream with known motion (the head turning on three axes with different periods, the jaw opening and
closing, the brows rising and falling, each on its own period so that no two are alike) is rendered on the 3D
head at true scale and tracked back with the face tracker. The tracked head angles are compared with the FAP
angles per axis (correlation and spread ratio: true amplitude gives 1), the tracked lip opening with the jaw,
the tracked brow heights with the raises, and the share of frames where the face was found is counted.

Pass marks (issue 37): |r| >= 0.9 per head axis with a spread ratio in 0.75-1.33, r >= 0.9 for the lips,
r >= 0.8 for the brows, the face found in >= 98 % of frames.

What the loop cannot see, a drawn frame can show: :func:`jaggedness` measures how jagged a frame is along a curve,
such as the chin's outline (:func:`chin_arc`) of a photo head whose jaw opens.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..fap.recorded import ENS_PER_EYE_WIDTH
from ..fap.stream import FapStream
from ..fap.table import RADIANS_PER_AU
from ..fap.units import AU_PER_DEGREE
from ..motion.face.lips import MNS_PER_EYE_WIDTH, inner_opening

#: Periods (s) and amplitudes of the known motion: pitch, yaw, roll in degrees; jaw in MNS; brows in ENS.
PERIODS_S = {"pitch": 4.1, "yaw": 5.3, "roll": 3.3, "jaw": 1.7, "brows": 2.3}
AMPLITUDES = {"pitch": 10.0, "yaw": 15.0, "roll": 8.0, "jaw": 500.0, "brows": 250.0}
PASS_HEAD_R, PASS_SPREAD, PASS_LIPS_R, PASS_BROWS_R, PASS_FOUND = 0.9, (0.75, 1.33), 0.9, 0.8, 0.98
#: :func:`jaggedness`: the smoothing along the curve, and how far either side of it the parallel curves go (px).
JAGGED_SMOOTHING_PX, JAGGED_REACH_PX = 4.0, 8
#: A landmark at a mouth corner: :func:`chin_arc` is the outline below it.
MOUTH_CORNER = 61


def known_motion(duration_s: float, *, fps: float = 30.0, amplitudes: dict[str, float] | None = None) -> FapStream:
    """The loop's FAP stream: head sinusoids, a jaw opening 0..amplitude, brows raised and lowered (sizes
    :data:`AMPLITUDES`, or ``amplitudes`` in their place)."""
    sizes = {**AMPLITUDES, **(amplitudes or {})}
    t = np.arange(round(duration_s * fps)) / fps
    degrees_to_au = AU_PER_DEGREE

    def wave(name: str, phase: float = 0.0) -> np.ndarray:
        return np.sin(2 * np.pi * t / PERIODS_S[name] + phase)

    curves = {48: sizes["pitch"] * degrees_to_au * wave("pitch"),
              49: sizes["yaw"] * degrees_to_au * wave("yaw", 0.7),
              50: sizes["roll"] * degrees_to_au * wave("roll", 1.9),
              3: sizes["jaw"] * 0.5 * (1 - np.cos(2 * np.pi * t / PERIODS_S["jaw"]))}
    brows = sizes["brows"] * wave("brows", 0.3)
    for fap in range(31, 37):
        curves[fap] = brows
    return FapStream.from_curves(curves, fps=fps, name="head loop")


def _read(path: Path) -> dict[str, np.ndarray]:
    with open(path, newline="") as handle:
        rows = list(csv.DictReader(handle))
    names = rows[0].keys() if rows else []
    return {name: np.array([float(row[name]) if row[name] else np.nan for row in rows]) for name in names}


@dataclass(frozen=True)
class LoopResult:
    """What came back: correlation and spread ratio per head axis, lips and brows r, share of frames found."""

    head_r: dict[str, float]
    head_spread: dict[str, float]
    lips_r: float
    brows_r: float
    found: float
    frames: int
    #: The control: the largest |r| of a tracked curve with a motion it was not given (another head axis, the
    #: jaw for the brows, the brows for the lips): what a channel leaking into another would show.
    crosstalk_r: float = float("nan")
    #: The tracker's ruler: the slope of what it reads (converted to FAP units as the tracked-motion readers do)
    #: over what was drawn, for the inner-lip opening (MNS) and the inner brows (ENS); 1 reads true size.
    lips_gain: float = float("nan")
    brows_gain: float = float("nan")

    @property
    def passed(self) -> bool:
        low, high = PASS_SPREAD
        return (all(abs(r) >= PASS_HEAD_R for r in self.head_r.values())
                and all(low <= s <= high for s in self.head_spread.values())
                and self.lips_r >= PASS_LIPS_R and self.brows_r >= PASS_BROWS_R and self.found >= PASS_FOUND)

    def lines(self) -> list[str]:
        head = ", ".join(f"{axis} r {self.head_r[axis]:.3f} spread {self.head_spread[axis]:.2f}"
                         for axis in self.head_r)
        return [f"frames {self.frames}, face found in {100 * self.found:.1f} %",
                f"head: {head}", f"lip opening vs jaw r {self.lips_r:.3f}, read at {self.lips_gain:.2f} x its size",
                f"brows r {self.brows_r:.3f}, read at {self.brows_gain:.2f} x their size",
                f"control: largest |r| of a tracked curve with a motion it was not given {self.crosstalk_r:.3f}",
                "pass" if self.passed else "FAIL"]


def measure(stream: FapStream, stem: str | Path) -> LoopResult:
    """Compare ``stream`` with what ``prosody track`` wrote at ``stem`` (``<stem>.head.csv`` and the rest)."""
    stem = Path(stem)
    head = _read(stem.with_name(stem.name + ".head.csv"))
    brows = _read(stem.with_name(stem.name + ".brows.csv"))
    mouth = _read(stem.with_name(stem.name + ".mouth.csv"))
    n = min(stream.n_frames, len(head["rx_rad"]))
    found = np.isfinite(head["rx_rad"][:n])

    def pair(truth: np.ndarray, tracked: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        keep = found & np.isfinite(tracked[:n])
        return truth[:n][keep], tracked[:n][keep]

    def r(truth: np.ndarray, tracked: np.ndarray) -> float:
        a, b = pair(truth, tracked)
        return float(np.corrcoef(a, b)[0, 1])

    axes = (("pitch", 48, "rx_rad"), ("yaw", 49, "ry_rad"), ("roll", 50, "rz_rad"))
    head_r, head_spread, crosstalk = {}, {}, []
    for axis, fap, column in axes:
        truth, tracked = pair(stream.curve(fap) * RADIANS_PER_AU, head[column])
        head_r[axis] = float(np.corrcoef(truth, tracked)[0, 1])
        head_spread[axis] = float(np.std(tracked) / np.std(truth))
        crosstalk += [abs(r(stream.curve(other), head[column])) for _, other, _ in axes if other != fap]
    heights = np.mean([brows[name] for name in ("inner_height_l", "inner_height_r", "outer_height_l",
                                                 "outer_height_r")], axis=0)
    lips_r, brows_r = r(stream.curve(3), mouth["lip_opening"]), r(stream.curve(31), heights)
    crosstalk += [abs(r(stream.curve(31), mouth["lip_opening"])), abs(r(stream.curve(3), heights))]

    def slope(truth: np.ndarray, tracked: np.ndarray) -> float:
        a, b = pair(truth, tracked)
        return float(np.polyfit(a, b, 1)[0]) if a.size > 1 and np.ptp(a) > 0 else float("nan")

    opening = inner_opening({f: stream.curve(f) for f in (3, 4, 5)})
    inner_brow = np.mean([brows["inner_height_l"], brows["inner_height_r"]], axis=0)
    return LoopResult(head_r, head_spread, lips_r, brows_r, float(found.mean()), n, max(crosstalk),
                      lips_gain=slope(opening, mouth["lip_opening"] / MNS_PER_EYE_WIDTH * 1024.0),
                      brows_gain=slope(stream.curve(31), inner_brow * ENS_PER_EYE_WIDTH))


def chin_arc(head) -> list[int]:
    """The lower half of a head's face outline (the landmark numbers below the mouth's corners at rest), in the
    outline's order from one side of the jaw round the chin to the other."""
    from ..head.mesh import face_outline

    loop = list(face_outline())
    rest_y = head.rig.mesh.vertices[:, 1]
    lower = [k for k in range(len(loop)) if rest_y[loop[k]] < rest_y[MOUTH_CORNER]]
    start = next(k for k in range(len(lower)) if (lower[k] - lower[k - 1]) % len(loop) != 1)
    return [loop[k] for k in lower[start:] + lower[:start]]


def jaggedness(frame: np.ndarray, points: np.ndarray) -> float:
    """How jagged ``frame`` (RGB) is along the curve through ``points`` (x, y pixels): the mean absolute grey level
    that a Gaussian smoothing over :data:`JAGGED_SMOOTHING_PX` along the curve takes off, on the curves parallel to
    it up to :data:`JAGGED_REACH_PX` either side. A saw-tooth along an edge raises it; the edge itself, crossing
    the curves, does not."""
    from scipy.ndimage import gaussian_filter1d, map_coordinates

    grey = np.asarray(frame, float) @ np.array([0.299, 0.587, 0.114])
    points = np.asarray(points, float)
    lengths = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))])
    at = np.arange(0.0, lengths[-1], 1.0)
    x, y = np.interp(at, lengths, points[:, 0]), np.interp(at, lengths, points[:, 1])
    dx, dy = np.gradient(x), np.gradient(y)
    norm = np.hypot(dx, dy) + 1e-9
    rows = [map_coordinates(grey, [y - d * dx / norm, x + d * dy / norm], order=1, mode="nearest")
            for d in range(-JAGGED_REACH_PX, JAGGED_REACH_PX + 1)]
    return float(np.mean([np.abs(row - gaussian_filter1d(row, JAGGED_SMOOTHING_PX)).mean() for row in rows]))


def folded_cells(renderer, values: np.ndarray) -> int:
    """How many of a photo head's person-layer cells off the face are turned over in the frame of ``values``
    (68 FAP values) against the rest frame: a cell whose corners change their winding shows the photo mirrored
    and squeezed, the layer folded over itself. ``renderer`` is a :class:`prosody.head.photo.PhotoRenderer`."""
    from ..head.mesh import face_outline
    from ..head.person import inside_polygon

    head = renderer.head
    triangles = head.layer_triangles
    outside = ~inside_polygon(head.layer_uv[triangles].mean(axis=1), head.uv[list(face_outline())])

    def winding(frame_values: np.ndarray) -> np.ndarray:
        corners = renderer.pixels(frame_values)[len(head.uv):][triangles]
        a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
        return np.sign((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))

    return int(np.sum((winding(np.asarray(values, float)) != winding(np.zeros(len(values)))) & outside))
