"""A drawn face animated from a FAP stream: head outline turning and tilting, brows rising (``prosody preview``).

The face is a small 3D model drawn in orthographic projection: an ellipsoid head that turns about a pivot at
the top of the neck, with eyes, nose, mouth and three points per eyebrow on its front. Angles and distances
are applied in FAP units at true scale (docs/fap.md): FAP 48-50 rotate the head (R = Rz(roll) Ry(yaw)
Rx(pitch), the signs of the .fap conventions: + pitch bows down, + yaw turns to the character's left, + roll
tilts to its right), and FAP 31-36 raise the inner, middle and outer brow points by ``value / 1024`` of the
model's eye-nose separation (ENS0). ``exaggerate`` multiplies both for viewing; the caption says so. The brows
are drawn at true size by default (:data:`BROW_VIEW_SCALE`); ``brow_scale`` draws them larger, which every
frame's caption then says.
The lips (FAP 3-7, 12-13) and the eyelids (FAP 19-22, in IRISD: the neutral lids rest on the iris, so the
opening between them is the iris diameter IRISD0) are drawn at true size.

A strip under the face plots the brow and head curves over a window around the current frame.

Writers: ``.gif`` with Pillow (no sound, for short excerpts), ``.mp4`` (H.264 + AAC) through an ffmpeg
executable, found on PATH or from the ``imageio-ffmpeg`` package, with the recording's audio muxed in.
"""

from __future__ import annotations

import contextlib
import itertools
import math
import os
import subprocess
import tempfile
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Union

import numpy as np

from audio_features.atomic import atomic_path, atomic_write, interrupts_held

from ..errors import ConfigError, PreviewError
from ..fap.stream import FapStream
from ..fap.table import DISTANCE_UNITS_PER_REFERENCE, HEAD_FAPS, RADIANS_PER_AU
from ..head.rig import rotation  # R = Rz(roll) Ry(yaw) Rx(pitch), the drawn face's and the 3D head's

if TYPE_CHECKING:
    from ..head.photo import PhotoHead

#: Frame widths drawn, in pixels (3840: a 4K frame; drawing is done at twice the size).
MIN_WIDTH, MAX_WIDTH = 64, 3840
#: Longest GIF written, in frames (Pillow keeps every GIF frame in memory); longer previews need MP4.
MAX_GIF_FRAMES = 1800
#: Most pixels a GIF's frames hold together (one byte each in memory while it is written: about 600 MB; the
#: default width's 1,800 frames are 518 million).
MAX_GIF_PIXELS = 600_000_000
#: Fastest GIF frame rate: a GIF's delays are whole hundredths of a second, and players slow shorter ones.
MAX_GIF_FPS = 50.0
#: Seconds of curve shown on each side of the current frame in the strip under the face.
STRIP_WINDOW_S = 3.0
#: Drawing is done at this multiple of the output size and scaled down, for smooth edges.
SUPERSAMPLE = 2

_BACKGROUND = (236, 238, 242)
_SKIN = (236, 200, 170)
_SKIN_EDGE = (150, 110, 85)
_SHOULDERS = (70, 90, 120)
_EYE_WHITE = (250, 250, 250)
_PUPIL = (40, 50, 70)
_NOSE = (185, 135, 105)
_MOUTH = (170, 70, 70)
_MOUTH_INSIDE = (90, 30, 40)
#: Brow colour; kept apart from every other colour of the face so that tests can find the brows' pixels.
BROW_COLOR = (20, 120, 30)
_CURVE_COLORS = {"brows": BROW_COLOR, "pitch": (200, 60, 40), "yaw": (40, 90, 200), "roll": (150, 80, 170)}


@dataclass(frozen=True)
class FaceModel:
    """Geometry of the drawn face, in head units (head half-height = 1): x toward the character's left
    (the viewer's right), y up, z toward the viewer. The head is an ellipsoid of semi-axes
    ``head_radii`` centred at the origin; it rotates about ``pivot`` (the top of the neck)."""

    head_radii: tuple[float, float, float] = (0.78, 1.0, 0.85)
    pivot: tuple[float, float, float] = (0.0, -0.85, -0.1)
    eye_x: float = 0.30
    eye_y: float = 0.10
    eye_radius: float = 0.10
    nose_bottom_y: float = -0.30
    nose_depth: float = 0.16
    mouth_y: float = -0.52
    mouth_half_width: float = 0.24
    #: Eyebrow points (inner, middle, outer) of the character's left brow; the right one mirrors it.
    brow_x: tuple[float, float, float] = (0.13, 0.30, 0.46)
    brow_y: tuple[float, float, float] = (0.30, 0.35, 0.30)
    #: Where the neutral eyelids cross the eye, as a share of its radius above and below its centre: the lids
    #: rest on the iris, so the opening between them is the iris diameter IRISD0.
    lid_rest: float = 0.75

    @property
    def irisd0(self) -> float:
        """Iris diameter (the IRISD reference distance): the opening between the neutral eyelids."""
        return 2 * self.lid_rest * self.eye_radius

    def eyelids(self, top_fap: float, bottom_fap: float) -> tuple[float, float]:
        """Heights (y) of the upper and lower eyelid of an eye, from its closing FAPs (19/20 top, 21/22 bottom,
        IRISD; positive closes): within the eye, and never past each other."""
        shift = self.irisd0 / DISTANCE_UNITS_PER_REFERENCE
        low, high = self.eye_y - self.eye_radius, self.eye_y + self.eye_radius
        top = min(high, max(low, self.eye_y + self.lid_rest * self.eye_radius - top_fap * shift))
        bottom = min(high, max(low, self.eye_y - self.lid_rest * self.eye_radius + bottom_fap * shift))
        if top < bottom:  # closed: the lids meet where they crossed
            top = bottom = (top + bottom) / 2
        return top, bottom

    @property
    def ens0(self) -> float:
        """Eye-nose separation (the ENS reference distance): eye line to the bottom of the nose."""
        return self.eye_y - self.nose_bottom_y

    def surface_z(self, x: float, y: float) -> float:
        """Depth of the head's front surface at (x, y)."""
        a, b, c = self.head_radii
        return c * math.sqrt(max(0.0, 1.0 - (x / a) ** 2 - (y / b) ** 2))


@dataclass(frozen=True)
class FacePose:
    """What one frame shows: head angles in radians and brow raises in ENS units (FAP units)."""

    pitch_rad: float = 0.0
    yaw_rad: float = 0.0
    roll_rad: float = 0.0
    #: Raise of (inner, middle, outer) for the character's left brow (FAP 31, 33, 35) and right (32, 34, 36).
    left_brow_ens: tuple[float, float, float] = (0.0, 0.0, 0.0)
    right_brow_ens: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: The lips, in their FAP units: FAP number -> value for 3 (jaw), 4 and 5 (mid lips), 6 and 7 (corners
    #: outwards, MW), 12 and 13 (corners up); absent is neutral.
    lip_faps: tuple[tuple[int, float], ...] = ()
    #: Eyelid closing (IRISD, positive closes): top left, top right, bottom left, bottom right (FAP 19-22).
    eyelids: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)


#: Lip FAPs the drawn mouth shows.
DRAWN_LIP_FAPS = (3, 4, 5, 6, 7, 12, 13)
#: Eyelid FAPs the drawn eyes show (top left, top right, bottom left, bottom right).
EYELID_FAPS = (19, 20, 21, 22)
#: Every FAP the drawn face shows.
DRAWN_FAPS = DRAWN_LIP_FAPS + EYELID_FAPS + (31, 32, 33, 34, 35, 36) + HEAD_FAPS


#: How much larger than true the brows are drawn by default: 1, true size (the brows' raises are people's size in
#: the stream itself; ``brow_scale`` above 1 is said on every frame).
BROW_VIEW_SCALE = 1.0


def poses(stream: FapStream, *, exaggerate: float = 1.0, brow_scale: float = BROW_VIEW_SCALE) -> list[FacePose]:
    """One pose per frame of ``stream``; FAPs masked off count as 0 (neutral)."""

    def curve(fap: int, fallback: int | None = None) -> np.ndarray:
        if fallback is not None and not stream.mask[:, fap - 1].any():
            fap = fallback
        return stream.curve(fap) * exaggerate  # 0 where masked off: neutral

    head = [curve(fap) * RADIANS_PER_AU for fap in HEAD_FAPS]
    # outer brows follow the middle ones when a stream has no FAP 35/36, as in the Live Link export
    left = [brow_scale * curve(31), brow_scale * curve(33), brow_scale * curve(35, fallback=33)]
    right = [brow_scale * curve(32), brow_scale * curve(34), brow_scale * curve(36, fallback=34)]
    # the lips at their true size: an exaggerated mouth is no longer a mouth
    lips = {fap: stream.curve(fap) for fap in DRAWN_LIP_FAPS if stream.mask[:, fap - 1].any()}
    lids = [stream.curve(fap) for fap in EYELID_FAPS]  # at true size too, as the lips
    return [FacePose(float(head[0][k]), float(head[1][k]), float(head[2][k]),
                     (float(left[0][k]), float(left[1][k]), float(left[2][k])),
                     (float(right[0][k]), float(right[1][k]), float(right[2][k])),
                     tuple((fap, float(values[k])) for fap, values in lips.items()),
                     (float(lids[0][k]), float(lids[1][k]), float(lids[2][k]), float(lids[3][k])))
            for k in range(stream.n_frames)]


class FaceRenderer:
    """Draws frames of ``width`` x ``height`` pixels (both even, for H.264): the face in the top square,
    the curve strip below it.

    Parameters
    ----------
    width : int in [64, 3840]
        Frame width in pixels; the height is ``width * 5 / 4`` rounded to an even number (``width`` without the
        strip).
    model : FaceModel, optional
        Face geometry.
    strip : bool
        Leave room for the curve strip below the face.
    """

    def __init__(self, width: int = 480, *, model: FaceModel | None = None, strip: bool = True,
                 face_height: int | None = None) -> None:
        if not (isinstance(width, (int, np.integer)) and MIN_WIDTH <= width <= MAX_WIDTH):
            raise ConfigError(f"preview width must be a whole number of pixels from {MIN_WIDTH} to {MAX_WIDTH}, "
                              f"got {width!r}")
        self.width = width + width % 2
        self.face_height = self.width if face_height is None else face_height + face_height % 2
        self.height = self.face_height + (2 * round(self.width / 8) if strip else 0)
        self.model = model or FaceModel()
        # head units -> pixels: the head (half-height 1) takes about 60 % of the face square
        self.scale = 0.30 * self.face_height
        self.center = (self.width / 2, self.face_height * 0.47)

    @property
    def ens_pixels(self) -> float:
        """Pixels per ENS0 (so a brow raise of ``v`` ENS units moves ``v / 1024 * ens_pixels`` pixels)."""
        return self.model.ens0 * self.scale

    def to_pixels(self, points: np.ndarray) -> np.ndarray:
        """Head-unit points (n, 3) in camera axes -> pixel (u, v), v pointing down."""
        u = self.center[0] + self.scale * points[:, 0]
        v = self.center[1] - self.scale * points[:, 1]
        return np.column_stack([u, v])

    # geometry -----------------------------------------------------------------------------------------
    def _posed(self, pose: FacePose, points: np.ndarray) -> np.ndarray:
        pivot = np.array(self.model.pivot)
        return pivot + (points - pivot) @ rotation(pose.pitch_rad, pose.yaw_rad, pose.roll_rad).T

    def head_outline(self, pose: FacePose, n_points: int = 96) -> np.ndarray:
        """The rotated head's silhouette in pixels, (n_points, 2): the orthographic outline of an ellipsoid
        is the ellipse of the Schur complement of its quadric over the depth axis."""
        a, b, c = self.model.head_radii
        r = rotation(pose.pitch_rad, pose.yaw_rad, pose.roll_rad)
        quadric = r @ np.diag([a ** -2, b ** -2, c ** -2]) @ r.T
        outline = quadric[:2, :2] - np.outer(quadric[:2, 2], quadric[2, :2]) / quadric[2, 2]
        eigenvalues, eigenvectors = np.linalg.eigh(outline)
        t = np.linspace(0.0, 2.0 * np.pi, n_points, endpoint=False)
        unit = np.column_stack([np.cos(t), np.sin(t)]) / np.sqrt(eigenvalues)
        center = self._posed(pose, np.zeros((1, 3)))[0]
        points = np.column_stack([center[0] + unit @ eigenvectors[0], center[1] + unit @ eigenvectors[1],
                                  np.zeros(n_points)])
        return self.to_pixels(points)

    def brow_points(self, pose: FacePose) -> dict[str, np.ndarray]:
        """Pixel polylines (inner, middle, outer) of the ``left`` and ``right`` brow (the character's)."""
        model, unit = self.model, self.model.ens0 / DISTANCE_UNITS_PER_REFERENCE
        brows = {}
        for side, sign, raises in (("left", 1.0, pose.left_brow_ens), ("right", -1.0, pose.right_brow_ens)):
            points = np.array([(sign * x, y + raise_ens * unit, model.surface_z(x, y) + 0.01)
                               for x, y, raise_ens in zip(model.brow_x, model.brow_y, raises, strict=True)])
            brows[side] = self.to_pixels(self._posed(pose, points))
        return brows

    def mouth_points(self, pose: FacePose) -> tuple[np.ndarray, np.ndarray]:
        """Face-model points (x, y, z) of the inner upper and lower lip, from corner to corner, unposed.

        FAP values are converted with the face's own MNS0 (nose bottom to mouth) and MW0 (mouth width): the
        jaw (FAP 3) and the bottom lip (FAP 5) move the lower lip, FAP 4 the upper one, FAP 6/7 and 12/13
        the corners.
        """
        m = self.model
        lips = dict(pose.lip_faps)
        mns = (m.nose_bottom_y - m.mouth_y) / DISTANCE_UNITS_PER_REFERENCE
        mw = 2 * m.mouth_half_width / DISTANCE_UNITS_PER_REFERENCE
        left = (m.mouth_half_width + lips.get(6, 0.0) * mw, m.mouth_y + lips.get(12, 0.0) * mns)
        right = (-(m.mouth_half_width + lips.get(7, 0.0) * mw), m.mouth_y + lips.get(13, 0.0) * mns)
        upper_middle = m.mouth_y - lips.get(4, 0.0) * mns
        lower_middle = m.mouth_y + (lips.get(5, 0.0) - lips.get(3, 0.0)) * mns
        t = np.linspace(0.0, 1.0, 13)
        x = right[0] + (left[0] - right[0]) * t
        corner_y = right[1] + (left[1] - right[1]) * t
        bulge = 1.0 - (2.0 * t - 1.0) ** 2  # 0 at the corners, 1 in the middle
        # at rest the mouth is a straight, neutral line; the middle of each lip stays where its own FAPs put it
        # while the corners move (FAP 12/13 up: a smile, down: sadness), so the lips bend between them
        corners_middle = (left[1] + right[1]) / 2
        upper = corner_y + bulge * (upper_middle - corners_middle)
        lower = corner_y + bulge * (lower_middle - corners_middle)
        z = np.array([m.surface_z(u, m.mouth_y) + 0.005 for u in x])
        return np.column_stack([x, upper, z]), np.column_stack([x, lower, z])

    def _feature(self, pose: FacePose, points: np.ndarray) -> np.ndarray | None:
        """Posed pixel points of a front feature, or None when it has turned away from the viewer."""
        posed = self._posed(pose, points)
        normal = rotation(pose.pitch_rad, pose.yaw_rad, pose.roll_rad)[2, 2]
        return self.to_pixels(posed) if normal > 0.05 else None

    def lid_cover(self, sign: float, height: float, *, upper: bool) -> np.ndarray:
        """Face-model points of the part of an eye (``sign`` +1: the character's left) that an eyelid at
        ``height`` covers: the arc beyond it, closed by the lid's edge."""
        m = self.model
        x0, y0, r = sign * m.eye_x, m.eye_y, m.eye_radius
        reach = math.asin(min(1.0, max(-1.0, (height - y0) / r)))
        t = np.linspace(reach, math.pi - reach, 16) if upper else np.linspace(math.pi - reach, 2 * math.pi + reach, 16)
        z = m.surface_z(x0, y0) + 0.006
        return np.column_stack([x0 + r * np.cos(t), y0 + r * np.sin(t), np.full(t.size, z)])

    def _circle(self, x: float, y: float, radius: float, n_points: int = 24) -> np.ndarray:
        t = np.linspace(0.0, 2.0 * np.pi, n_points, endpoint=False)
        z = self.model.surface_z(x, y) + 0.005
        return np.column_stack([x + radius * np.cos(t), y + radius * np.sin(t), np.full(n_points, z)])

    # drawing ------------------------------------------------------------------------------------------
    def render(self, pose: FacePose, *, strip: np.ndarray | None = None, caption: str = "") -> np.ndarray:
        """One RGB frame (height, width, 3) uint8 of ``pose``; ``strip`` is a prepared strip image."""
        from PIL import Image, ImageDraw

        s = SUPERSAMPLE
        image = Image.new("RGB", (self.width * s, self.face_height * s), _BACKGROUND)
        draw = ImageDraw.Draw(image)

        def flat(points: np.ndarray) -> list[tuple[float, float]]:
            return [(float(u) * s, float(v) * s) for u, v in points]

        w, fh = self.width, self.face_height
        # shoulders and neck stay still: they show how far the head moves
        draw.ellipse([w * 0.12 * s, fh * 0.86 * s, w * 0.88 * s, fh * 1.35 * s], fill=_SHOULDERS)
        neck_top = self.to_pixels(np.array([[-0.32, -0.6, 0.0], [0.32, -0.6, 0.0]]))
        draw.rectangle([neck_top[0, 0] * s, neck_top[0, 1] * s, neck_top[1, 0] * s, fh * 0.92 * s], fill=_SKIN)
        draw.polygon(flat(self.head_outline(pose)), fill=_SKIN, outline=_SKIN_EDGE, width=2 * s)

        m = self.model
        for sign in (1.0, -1.0):
            eye = self._feature(pose, self._circle(sign * m.eye_x, m.eye_y, m.eye_radius))
            pupil = self._feature(pose, self._circle(sign * m.eye_x, m.eye_y - 0.01, m.eye_radius * 0.45))
            if eye is not None and pupil is not None:
                draw.polygon(flat(eye), fill=_EYE_WHITE, outline=_SKIN_EDGE, width=s)
                draw.polygon(flat(pupil), fill=_PUPIL)
                # the lids cover the eye above and below them; their edges are drawn as lash lines
                top_fap, bottom_fap = pose.eyelids[0 if sign > 0 else 1], pose.eyelids[2 if sign > 0 else 3]
                lid_top, lid_bottom = m.eyelids(top_fap, bottom_fap)
                for height, is_upper in ((lid_top, True), (lid_bottom, False)):
                    cover = self._feature(pose, self.lid_cover(sign, height, upper=is_upper))
                    if cover is not None:
                        draw.polygon(flat(cover), fill=_SKIN, outline=_SKIN_EDGE, width=s)
                        draw.line(flat(cover[[0, -1]]), fill=_SKIN_EDGE, width=2 * s)
        bridge_z, base_z = m.surface_z(0.0, m.eye_y - 0.05), m.surface_z(0.0, m.nose_bottom_y)
        nose = self._feature(pose, np.array([
            [0.0, m.eye_y - 0.05, bridge_z], [0.0, m.nose_bottom_y + 0.04, base_z + m.nose_depth],
            [-0.07, m.nose_bottom_y, base_z + 0.02], [0.07, m.nose_bottom_y, base_z + 0.02],
            [0.0, m.nose_bottom_y + 0.04, base_z + m.nose_depth]]))
        if nose is not None:
            draw.line(flat(nose), fill=_NOSE, width=3 * s, joint="curve")
        upper, lower = self.mouth_points(pose)
        top, bottom = self._feature(pose, upper), self._feature(pose, lower)
        if top is not None and bottom is not None:
            if np.min(lower[:, 1] - upper[:, 1]) < -0.004:  # lips apart: the mouth's inside shows
                draw.polygon(flat(np.vstack([top, bottom[::-1]])), fill=_MOUTH_INSIDE)
            draw.line(flat(top), fill=_MOUTH, width=4 * s, joint="curve")
            draw.line(flat(bottom), fill=_MOUTH, width=4 * s, joint="curve")
        if self._feature(pose, np.zeros((1, 3))) is not None:
            for points in self.brow_points(pose).values():
                draw.line(flat(points), fill=BROW_COLOR, width=5 * s, joint="curve")

        return self.compose(np.asarray(image.reduce(s)), strip=strip, caption=caption)  # box average of s x s

    def compose(self, face: np.ndarray, *, strip: np.ndarray | None = None, caption: str = "") -> np.ndarray:
        """The frame: ``face`` (face_height, width, 3) on top, the strip below it, the caption over the face."""
        from PIL import Image, ImageDraw

        frame = Image.new("RGB", (self.width, self.height), _BACKGROUND)
        frame.paste(Image.fromarray(face), (0, 0))
        if strip is not None:
            frame.paste(Image.fromarray(strip), (0, self.face_height))
        if caption:
            ImageDraw.Draw(frame).text((6, 4), caption, fill=(60, 60, 60))
        return np.asarray(frame)


class CurveStrip:
    """The strip under the face: brow raise and head angles over +-``STRIP_WINDOW_S`` around the frame."""

    def __init__(self, stream: FapStream, *, width: int, height: int,
                 scales: tuple[float, float] | None = None) -> None:
        self.width, self.height, self.fps = width, height, stream.fps
        self.half_window = max(1, round(STRIP_WINDOW_S * stream.fps))

        brows = stream.curve(31)  # 0 where masked off
        head = stream.curves(HEAD_FAPS)
        # each group on its own scale (its largest magnitude), so both fill the strip; strips shown side by
        # side share the scales they are given, so that equal heights mean equal motion
        brow_scale, head_scale = scales if scales is not None else strip_scales([stream])
        has_brows = bool(stream.mask[:, 30].any())
        has_head = bool(stream.mask[:, 47:50].any())
        self.curves = {}
        if has_brows:
            self.curves["brows"] = brows / brow_scale
        if has_head:
            self.curves.update(pitch=head[:, 0] / head_scale, yaw=head[:, 1] / head_scale,
                               roll=head[:, 2] / head_scale)
        degrees = math.degrees(head_scale * RADIANS_PER_AU)
        self.labels = (f"brows (full scale {brow_scale:.0f} ENS)" if has_brows else "brows: not in this stream",
                       f"head, full scale {degrees:.1f} deg:" if has_head else "head: not in this stream")
        self.short_labels = (f"brows {brow_scale:.0f} ENS" if has_brows else "no brows",
                             f"head {degrees:.1f} deg" if has_head else "no head")

    def render(self, frame: int) -> np.ndarray:
        from PIL import Image, ImageDraw

        image = Image.new("RGB", (self.width, self.height), (250, 250, 252))
        draw = ImageDraw.Draw(image)
        w, h = self.width, self.height
        middle = h * 0.55
        draw.line([(0, middle), (w, middle)], fill=(215, 215, 220))
        first = frame - self.half_window
        span = 2 * self.half_window
        for name, values in self.curves.items():
            lo, hi = max(first, 0), min(frame + self.half_window + 1, len(values))
            if hi - lo < 2:
                continue
            x = (np.arange(lo, hi) - first) * (w - 1) / span
            y = middle - values[lo:hi] * h * 0.38
            draw.line(list(zip(x.tolist(), y.tolist(), strict=True)), fill=_CURVE_COLORS[name], width=2)
        draw.line([(w / 2, 0), (w / 2, h)], fill=(90, 90, 90))
        brow_label, head_label = self.labels
        names = ["pitch", "yaw", "roll"] if "pitch" in self.curves else []
        legend = sum(draw.textlength(name) + 5 for name in names)
        if draw.textlength(brow_label) > w / 2 - 6 or draw.textlength(head_label) + legend > w / 2 - 6:
            # a narrow strip (side-by-side panels): the short forms
            brow_label, head_label = self.short_labels
            names = [name[0] for name in names]
        draw.text((4, 2), brow_label, fill=BROW_COLOR)
        label_x = w / 2 + 4
        draw.text((label_x, 2), head_label, fill=(70, 70, 70))
        label_x += draw.textlength(head_label)
        for name, full in zip(names, ("pitch", "yaw", "roll"), strict=False):  # the legend, in the curves' colours
            draw.text((label_x + 5, 2), name, fill=_CURVE_COLORS[full])
            label_x += draw.textlength(name) + 5
        return np.asarray(image)


def strip_scales(streams: list[FapStream]) -> tuple[float, float]:
    """The strip's (brow ENS, head AU) scales that fit every stream: their largest magnitudes (at least 1)."""
    brow = max([float(np.max(np.abs(s.curve(31)), initial=0.0)) for s in streams] + [1.0])
    head = max([float(np.max(np.abs(s.curves(HEAD_FAPS)), initial=0.0)) for s in streams] + [1.0])
    return brow, head


#: The faces a preview can show by name: the 3D head (every FAP it has a part for) or the drawn diagnostic
#: face; a photo's path (:data:`PHOTO_ENDINGS`) shows that person's head.
FACES = ("head", "drawn")
PHOTO_ENDINGS = (".jpg", ".jpeg", ".png")
#: A face as the previews take it: a name of :data:`FACES`, a photo's path, or a ``PhotoHead``.
Face = Union[str, "os.PathLike[str]", "PhotoHead"]


def head_values(stream: FapStream, *, exaggerate: float = 1.0, brow_scale: float = BROW_VIEW_SCALE) -> np.ndarray:
    """The (frames, 68) FAP values the head shows: masked-off FAPs 0 (neutral); head angles and brow raises
    times ``exaggerate``, the brows ``brow_scale`` times more; outer brows following the middle ones where the
    stream has none (as in the Live Link export)."""
    values = np.where(stream.mask, np.nan_to_num(stream.values), 0.0)
    for outer, middle in ((35, 33), (36, 34)):
        if not stream.mask[:, outer - 1].any():
            values[:, outer - 1] = values[:, middle - 1]
    values[:, 30:36] *= exaggerate * brow_scale
    values[:, 47:50] *= exaggerate
    return values


def render_frames(stream: FapStream, *, width: int = 480, exaggerate: float = 1.0,
                  brow_scale: float = BROW_VIEW_SCALE,
                  first_frame: int = 0, n_frames: int | None = None, strip: bool = True,
                  label: str | None = None, scales: tuple[float, float] | None = None,
                  captioned: bool = True, face: Face = "head") -> Iterator[np.ndarray]:
    """Frames of the preview of ``stream``, one RGB array (height, width, 3) uint8 per stream frame.

    Parameters
    ----------
    stream : FapStream
        Head (FAP 48-50) and brow (FAP 31-36) motion; other FAPs are not drawn.
    width : int in [64, 3840]
        Frame width in pixels (height = 5/4 of it, even).
    exaggerate : float > 0
        Multiplies head angles and brow raises as drawn (1 = true scale).
    brow_scale : float > 0
        Draws the brow raises this much larger again (default :data:`BROW_VIEW_SCALE`; 1: true size).
    first_frame, n_frames : int
        The excerpt to draw (default: the whole stream).
    strip : bool
        Draw the curve strip under the face (False: the frame is the face square alone).
    label : str, optional
        Caption of every frame instead of the stream's name.
    scales : (float, float), optional
        The strip's brow (ENS) and head (AU) scales; default: this stream's largest magnitudes.
    captioned : bool
        Write the name, time and drawing scale at the top (False: the face alone, as a study shows it).
    face : {"head", "drawn"}, PhotoHead or path of a photo
        The 3D head (:mod:`prosody.head`, every FAP it has a part for), the drawn face (head, brows, lips
        and lids only; a diagnostic), or a person's head made from a photo (:func:`prosody.head.photo.photo_head`;
        the frame keeps the photo's proportions).

    Examples
    --------
    >>> import numpy as np
    >>> stream = FapStream.from_curves({31: np.array([0.0, 400.0])}, fps=30)
    >>> [frame.shape for frame in render_frames(stream, width=64, strip=False)]
    [(64, 64, 3), (64, 64, 3)]
    """
    if not exaggerate > 0:
        raise ConfigError(f"exaggerate must be a positive number, got {exaggerate!r}")
    if not (math.isfinite(brow_scale) and brow_scale > 0):
        raise ConfigError(f"brow_scale must be a positive number, got {brow_scale!r}", parameter="brow_scale")
    resolved = resolve_face(face)
    photo = None if isinstance(resolved, str) else resolved
    face = resolved
    if photo is not None:
        from ..head.photo import PhotoRenderer

        photo_renderer = PhotoRenderer(photo, width + width % 2)
        renderer = FaceRenderer(width, strip=strip, face_height=photo_renderer.height)
    else:
        renderer = FaceRenderer(width, strip=strip)
    curves = CurveStrip(stream, width=renderer.width, height=max(1, renderer.height - renderer.face_height),
                        scales=scales)
    last = stream.n_frames if n_frames is None else min(stream.n_frames, first_frame + n_frames)
    excerpt = FapStream(stream.values[first_frame:last], stream.mask[first_frame:last], stream.fps, stream.name)
    note = (f"  x{exaggerate:g}" if exaggerate != 1 else "") + (
        f"  brows x{exaggerate * brow_scale:g}" if brow_scale != 1 and stream.mask[:, 30:36].any() else "")
    def caption(frame: int) -> str:
        return f"{label or stream.name}  {frame / stream.fps:7.2f} s{note}" if captioned else ""

    if face == "drawn":
        for offset, pose in enumerate(poses(excerpt, exaggerate=exaggerate, brow_scale=brow_scale)):
            frame = first_frame + offset
            yield renderer.render(pose, strip=curves.render(frame) if strip else None, caption=caption(frame))
        return
    from ..head.render import HeadRenderer

    head = photo_renderer if photo is not None else HeadRenderer(renderer.width, renderer.face_height)
    for offset, values in enumerate(head_values(excerpt, exaggerate=exaggerate, brow_scale=brow_scale)):
        frame = first_frame + offset
        yield renderer.compose(head.render(values), strip=curves.render(frame) if strip else None,
                               caption=caption(frame))


def resolve_face(face: Face) -> str | PhotoHead:
    """``face`` as :func:`render_frames` takes it: ``"head"`` or ``"drawn"``, or a :class:`PhotoHead` (a path
    of a photo is made into one).

    Raises
    ------
    ConfigError
        Neither a face's name nor a file.
    PhotoError
        The photo cannot become a head (see :func:`prosody.head.photo.photo_head`).
    """
    from ..head.photo import PhotoHead, photo_head

    if isinstance(face, PhotoHead) or face in FACES:
        return face
    if isinstance(face, (str, os.PathLike)) and Path(face).suffix.lower() in PHOTO_ENDINGS:
        return photo_head(face)
    raise ConfigError(f"the face is {', '.join(FACES)} or a photo ({', '.join(PHOTO_ENDINGS)}), not {face!r}")


def face_size(face, width: int | None) -> int:
    """The frame width for ``face``: ``width``, or by default 480, or a photo's own width (at most
    :data:`MAX_WIDTH`)."""
    if width is not None:
        return width
    from ..head.photo import PhotoHead

    return min(face.width, MAX_WIDTH) if isinstance(face, PhotoHead) else 480


def find_ffmpeg() -> str | None:
    """An ffmpeg executable: ``ffmpeg`` on PATH, else the one the ``imageio-ffmpeg`` package ships, else None
    (the one the audio reader uses for MP4 sound: :func:`audio_features.audio.find_ffmpeg`)."""
    from audio_features.audio import find_ffmpeg as found

    return found()


def excerpt_frames(n_frames: int, fps: float, start_s: float, duration_s: float | None) -> tuple[int, int]:
    """The first frame and the number of frames of the excerpt from ``start_s`` lasting ``duration_s`` (default:
    to the end): the frame showing ``start_s`` first (0.099 s of a 0.10 s stream at 30 fps is its third), then
    at least one frame."""
    if n_frames == 0:
        raise PreviewError("the stream has no frames: nothing to draw")
    if not start_s >= 0 or (duration_s is not None and not duration_s > 0):
        raise ConfigError(f"the excerpt needs start >= 0 and duration > 0, got {start_s!r} and {duration_s!r}")
    first = math.floor(start_s * fps + 1e-9)
    if first >= n_frames:
        raise ConfigError(f"start {start_s:g} s is past the end of the stream ({n_frames / fps:.2f} s)")
    count = n_frames - first if duration_s is None else min(n_frames - first, max(1, round(duration_s * fps)))
    return first, count


def check_gif(path: Path, *, fps: float, n_frames: int, width: int, height: int) -> None:
    """Refuse a GIF too long, too large to hold in memory, or faster than its delays can say."""
    if n_frames > MAX_GIF_FRAMES:
        raise PreviewError(f"{path}: a GIF of {n_frames} frames is too long (at most {MAX_GIF_FRAMES}, "
                           f"{MAX_GIF_FRAMES / fps:.0f} s at {fps:g} fps); write .mp4, or choose an excerpt "
                           "with start_s= and duration_s=")
    if n_frames * width * height > MAX_GIF_PIXELS:
        most = max(1, MAX_GIF_PIXELS // (width * height))
        raise PreviewError(f"{path}: a GIF of {n_frames} frames of {width} x {height} would hold "
                           f"{n_frames * width * height / 1e9:.1f} GB while it is written (at most "
                           f"{MAX_GIF_PIXELS / 1e9:.1f}: {most} frames at this size); write .mp4, a smaller width, "
                           "or an excerpt")
    if fps > MAX_GIF_FPS:
        raise PreviewError(f"{path}: a GIF's frame delays are whole hundredths of a second and players slow those "
                           f"under 0.02 s: {fps:g} fps is too fast for a GIF (at most {MAX_GIF_FPS:g}); write .mp4, "
                           "or resample the stream")


def _write_gif(frames: Iterator[np.ndarray], path: Path, *, fps: float) -> None:
    from PIL import Image

    images = [Image.fromarray(frame).quantize(colors=64, method=Image.Quantize.MEDIANCUT) for frame in frames]
    if not images:
        raise PreviewError(f"{path}: nothing to draw (the excerpt has no frames)")
    # GIF delays are whole centiseconds: round the cumulative time so that the animation keeps pace with fps
    ends = np.round(np.arange(1, len(images) + 1) * 100.0 / fps) * 10
    durations = np.diff(np.concatenate([[0.0], ends])).astype(int).tolist()
    with atomic_write(path, mode="wb") as handle:
        images[0].save(handle, format="GIF", save_all=True, append_images=images[1:], duration=durations,
                       loop=0, disposal=1, optimize=False)


def _write_mp4(frames: Iterator[np.ndarray], path: Path, *, fps: float, width: int, height: int,
               ffmpeg: str, audio: Path | None, start_s: float, duration_s: float) -> None:
    command = [ffmpeg, "-hide_banner", "-loglevel", "error", "-y",
               "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{width}x{height}", "-framerate", f"{fps:.12g}",
               "-i", "pipe:0"]
    if audio is not None:
        command += ["-ss", f"{start_s:.6f}", "-t", f"{duration_s:.6f}", "-i", str(audio),
                    "-map", "0:v:0", "-map", "1:a:0?", "-c:a", "aac", "-b:a", "128k"]
    command += ["-c:v", "libx264", "-preset", "veryfast", "-crf", "20", "-pix_fmt", "yuv420p",
                "-movflags", "+faststart", "-f", "mp4"]
    with atomic_path(path) as partial, tempfile.TemporaryFile() as errors:
        process: subprocess.Popen | None = None
        try:
            # an interrupt while ffmpeg starts would leave it running, and writing the file: it waits until
            # the process is known, to be killed
            with interrupts_held():
                process = subprocess.Popen([*command, str(partial)], stdin=subprocess.PIPE, stderr=errors)
            assert process.stdin is not None
            for frame in frames:
                process.stdin.write(np.ascontiguousarray(frame).tobytes())
            process.stdin.close()
        except BrokenPipeError:
            pass  # ffmpeg stopped reading: its exit code and message say why
        except BaseException:
            if process is not None:
                process.kill()
                process.wait()
            raise
        finally:
            if process is not None and process.stdin is not None:
                with contextlib.suppress(BrokenPipeError):
                    process.stdin.close()
        assert process is not None
        if process.wait() != 0:
            errors.seek(0)
            detail = errors.read().decode("utf-8", "replace").strip().splitlines()
            raise PreviewError(f"{path}: ffmpeg failed ({detail[-1] if detail else f'exit {process.returncode}'})")


def _reporting(frames: Iterator[np.ndarray], progress: Callable[[int, int], None],
               total: int) -> Iterator[np.ndarray]:
    for done, frame in enumerate(frames, start=1):
        yield frame
        progress(done, total)


def write_preview(stream: FapStream, output: str | os.PathLike[str], *, audio: str | os.PathLike[str] | None = None,
                  width: int | None = None, exaggerate: float = 1.0, start_s: float = 0.0,
                  duration_s: float | None = None, ffmpeg: str | None = "auto",
                  progress: Callable[[int, int], None] | None = None,
                  scales: tuple[float, float] | None = None, brow_scale: float = BROW_VIEW_SCALE,
                  strip: bool = True, captioned: bool = True, face: Face = "head") -> Path:
    """Write the preview of ``stream`` (the 3D head, a photo's head, or the drawn face) to ``output`` (``.mp4``
    or ``.gif``).

    Parameters
    ----------
    stream : FapStream
        The motion to show (FAP 48-50 and 31-36).
    output : path ending in .mp4 or .gif
        File to write, atomically.
    audio : path, optional
        The recording, muxed into an MP4 (over the same excerpt); GIFs have no sound.
    width : int in [64, 3840], optional
        Frame width in pixels (default 480, or a photo's own width).
    exaggerate : float > 0
        Multiplies the drawn motion (1 = true scale).
    brow_scale : float > 0
        Draws the brow raises this much larger again (default 1: true size; another value is said on every
        frame).
    start_s, duration_s : float >= 0
        The excerpt to show, in seconds (default: all of it).
    ffmpeg : str or None
        ffmpeg executable for MP4; ``"auto"`` looks it up with :func:`find_ffmpeg`.
    progress : callable, optional
        Called as ``progress(frames_drawn, frames_total)`` after every frame.
    scales : (float, float), optional
        Full scale of the strip's brow (ENS) and head (AU) curves; default: this stream's largest values.
        Give the same scales to previews that will be compared.
    strip, captioned : bool
        Draw the curve strip and the caption (False and False: the face alone, a study's stimulus).
    face : {"head", "drawn"}, PhotoHead or path of a JPEG or PNG photo
        The 3D head (default), the drawn diagnostic face, or the head of the person in a photo.

    Returns
    -------
    Path of the written file.
    """
    if scales is not None and not all(math.isfinite(v) and v > 0 for v in scales):
        raise ConfigError(f"strip scales must be positive numbers, got {scales!r}")
    return _write_video([(None, stream)], output, audio=audio, width=width, exaggerate=exaggerate,
                        brow_scale=brow_scale, start_s=start_s, duration_s=duration_s, ffmpeg=ffmpeg,
                        progress=progress, scales=scales, strip=strip, captioned=captioned, face=face)


def write_side_by_side(streams: Mapping[str, FapStream], output: str | os.PathLike[str], *,
                       audio: str | os.PathLike[str] | None = None, panel_width: int = 320,
                       exaggerate: float = 1.0, start_s: float = 0.0, duration_s: float | None = None,
                       ffmpeg: str | None = "auto", progress: Callable[[int, int], None] | None = None,
                       brow_scale: float = BROW_VIEW_SCALE, face: Face = "head") -> Path:
    """One video of several streams side by side, each face labelled with its name, with the recording's
    audio: the stimulus of a paired-comparison study, and the quickest way to judge the motion by eye.

    The curve strips share one scale, so equal heights mean equal motion. Parameters as
    :func:`write_preview`; ``streams`` maps labels to streams of one length and rate, drawn left to right.
    """
    if not streams:
        raise ConfigError("no stream to draw")
    return _write_video(list(streams.items()), output, audio=audio, width=panel_width, exaggerate=exaggerate,
                        brow_scale=brow_scale, start_s=start_s, duration_s=duration_s, ffmpeg=ffmpeg,
                        progress=progress, scales=None, face=face)


def _write_video(panels: list[tuple[str | None, FapStream]], output: str | os.PathLike[str], *,
                 audio: str | os.PathLike[str] | None, width: int | None, exaggerate: float, brow_scale: float,
                 start_s: float,
                 duration_s: float | None, ffmpeg: str | None, progress: Callable[[int, int], None] | None,
                 scales: tuple[float, float] | None, strip: bool = True, captioned: bool = True,
                 face: Face = "head") -> Path:
    """The panels (label, stream) side by side as one .mp4 or .gif; the strips share ``scales`` (default:
    what fits every stream)."""
    path = Path(output)
    kind = path.suffix.lower()
    if kind not in (".mp4", ".gif"):
        raise ConfigError(f"{path}: the video is written as .mp4 or .gif, not {kind or 'a file with no ending'!r}")
    n, fps = panels[0][1].n_frames, panels[0][1].fps
    if any(s.n_frames != n or s.fps != fps for _, s in panels):
        raise ConfigError("streams side by side must have one length and frame rate")
    first, count = excerpt_frames(n, fps, start_s, duration_s)
    shared = scales if scales is not None else strip_scales([s for _, s in panels])
    face = resolve_face(face)
    width = face_size(face, width)
    drawn = [render_frames(s, width=width, exaggerate=exaggerate, brow_scale=brow_scale, first_frame=first,
                           n_frames=count, label=label, scales=shared, strip=strip, captioned=captioned,
                           face=face)
             for label, s in panels]
    frames: Iterator[np.ndarray] = drawn[0] if len(drawn) == 1 else (np.hstack(row) for row in zip(*drawn,
                                                                                                  strict=True))
    if progress is not None:
        frames = _reporting(frames, progress, count)
    if kind == ".gif":
        if count > MAX_GIF_FRAMES or fps > MAX_GIF_FPS:
            check_gif(path, fps=fps, n_frames=count, width=1, height=1)  # before a frame is drawn
        first_gif = next(frames, None)
        if first_gif is not None:
            check_gif(path, fps=fps, n_frames=count, width=first_gif.shape[1], height=first_gif.shape[0])
            frames = itertools.chain([first_gif], frames)
        _write_gif(frames, path, fps=fps)
        return path
    executable = find_ffmpeg() if ffmpeg == "auto" else ffmpeg
    if executable is None:
        raise PreviewError(f"{path}: MP4 needs ffmpeg; install it (or `pip install imageio-ffmpeg`), "
                           "or write a .gif")
    first_frame = next(frames, None)
    if first_frame is None:
        raise PreviewError(f"{path}: nothing to draw (the excerpt has no frames)")
    _write_mp4(itertools.chain([first_frame], frames), path, fps=fps, width=first_frame.shape[1],
               height=first_frame.shape[0], ffmpeg=executable, audio=Path(audio) if audio is not None else None,
               start_s=first / fps,
               duration_s=count / fps)
    return path
