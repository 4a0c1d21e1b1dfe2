"""The head for the browser: the model the pages' WebGL code (``head.js``) draws, as JSON.

The JSON holds what :class:`~prosody.head.render.HeadRenderer` uses, so both draw one head: the rest
vertices, triangles, colours and which vertices turn with the head; every FAP's field as sparse
(vertex, dx, dy, dz) lists in cm per FAP unit; the neck pivot; the camera (distance, look-at height, half view)
and the lights. ``head.js`` deforms the mesh on the CPU (rest + sum of value x field), turns the head in the
vertex shader (R = Rz(roll) Ry(yaw) Rx(pitch) about the pivot) and shades per pixel as the CPU renderer does.
"""

from __future__ import annotations

import functools
import json
from importlib import resources

import numpy as np

from ..fap.table import HEAD_FAPS, N_FAPS
from . import view
from .mesh import NECK_PIVOT
from .rig import HeadRig, head_rig

#: Decimal places kept: 1e-4 cm for positions, 1e-8 cm per unit for fields (their values times ~1000).
_POSITION_DIGITS, _FIELD_DIGITS = 4, 8


def model_document(rig: HeadRig | None = None) -> dict:
    """The head model as a JSON-ready dict (see the module doc)."""
    rig = rig or head_rig()
    mesh = rig.mesh
    fields = {}
    for fap in rig.supported:
        if fap in HEAD_FAPS:
            continue
        field = rig.fields[fap - 1].astype(np.float64)
        moved = np.flatnonzero(np.abs(field).max(axis=1) > 1e-9)
        if moved.size:
            fields[str(fap)] = {"vertices": moved.tolist(),
                                "offsets": np.round(field[moved], _FIELD_DIGITS).reshape(-1).tolist()}
    return {
        "format": "visual-prosody-head", "version": 1,
        "vertices": np.round(mesh.vertices.astype(np.float64), _POSITION_DIGITS).reshape(-1).tolist(),
        "triangles": mesh.triangles.reshape(-1).tolist(),
        "colors": np.round(mesh.colors.astype(np.float64), 4).reshape(-1).tolist(),
        "rotates": np.round(mesh.turn_share(), 3).tolist(),
        "fields": fields,
        "supported": list(rig.supported),
        "pivot": list(NECK_PIVOT),
        "camera": {"distance_cm": view.CAMERA_DISTANCE_CM, "look_at_y_cm": view.LOOK_AT_Y_CM,
                   "half_view_cm": view.HALF_VIEW_CM},
        "background": list(view.BACKGROUND),
        "lights": {"directions": view.light_directions().tolist(), "key": view.KEY, "fill": view.FILL,
                   "ambient": view.AMBIENT, "specular": view.SPECULAR, "shininess": 2 ** view.SHININESS_DOUBLINGS},
    }


HEAD_FRAMES_FORMAT = "visual-prosody-head-frames"


def head_frames_document(values: np.ndarray, *, fps: float) -> dict:
    """The frames a page plays on the head: ``values`` (frames, 68), as the head shows them (brow and head
    scaling applied), kept for the FAPs that move; ``{"format", "version", "fps", "faps", "frames"}``."""
    values = np.asarray(values, float)
    moving = [int(f) + 1 for f in np.flatnonzero(np.any(values != 0, axis=0))]
    frames = np.round(values[:, [f - 1 for f in moving]], 3) if moving else np.zeros((len(values), 0))
    return {"format": HEAD_FRAMES_FORMAT, "version": 1, "fps": fps, "faps": moving, "frames": frames.tolist()}


@functools.lru_cache(maxsize=1)
def model_json() -> bytes:
    """:func:`model_document` of the canonical head, encoded once."""
    return json.dumps(model_document(), separators=(",", ":")).encode("utf-8")


def head_script() -> bytes:
    """The WebGL drawing code (``head.js``) the pages load."""
    return resources.files("prosody.head").joinpath("head.js").read_bytes()


PHOTO_TEXTURE_PATH, PHOTO_BACKGROUND_PATH = "/face.png", "/background.jpg"


def photo_model_document(head) -> dict:
    """The head of a photo (:class:`~prosody.head.photo.PhotoHead`) for ``head.js``: what
    :class:`~prosody.head.photo.PhotoRenderer` draws, in the photo's axes (pixels: x right, y up, z towards the
    camera). Every vertex's rest position; the fields of the face's FAPs in pixels per unit, the person's grid
    following the face's skin as the renderer's does; each vertex's share of the head's turn about the pivot;
    which vertices show the photo (``uv``, 0..1 from the top-left corner) and which are lit (the mouth's inside);
    the photo's size and its camera for the motion's perspective; the images at :data:`PHOTO_TEXTURE_PATH` and
    :data:`PHOTO_BACKGROUND_PATH` (:func:`photo_images`)."""
    from .photo import (
        CAMERA_DISTANCE_CM,
        INSIDE_SOFTNESS_PX,
        MOUTH_DEPTH_BIAS_CM,
        RELIGHT_AMBIENT,
        RELIGHT_DIRECTION,
        RELIGHT_RANGE,
        PhotoRenderer,
    )

    renderer = PhotoRenderer(head)
    rest = renderer.vertices(np.zeros(N_FAPS))
    n_rig = head.rig.mesh.n_vertices
    fields = {}
    for fap in head.rig.supported:
        if fap in HEAD_FAPS:
            continue
        field = renderer.field(fap)
        moved = np.flatnonzero(np.abs(field).max(axis=1) > 1e-6)
        if moved.size:
            fields[str(fap)] = {"vertices": moved.tolist(),
                                "offsets": np.round(field[moved], 6).reshape(-1).tolist()}
    uv = renderer.uv / np.array(head.texture_size)
    textured = np.isin(np.arange(len(rest)), np.unique(renderer.triangles[renderer.textured]))
    rest_normals, relit = renderer.relit
    return {
        "format": "visual-prosody-head", "version": 1, "kind": "photo",
        "vertices": np.round(rest, 3).reshape(-1).tolist(),
        "triangles": renderer.triangles.reshape(-1).tolist(),
        "colors": np.round(renderer.colors, 4).reshape(-1).tolist(),
        "textured": textured.astype(int).tolist(),
        "uv": np.round(uv, 5).reshape(-1).tolist(),
        "behind": np.round(renderer.behind_px, 3).tolist(),
        "rotates": np.round(renderer.follows, 3).tolist(),
        "relight": {"normals": np.round(rest_normals, 4).reshape(-1).tolist(), "shares": np.round(relit, 3).tolist(),
                    "direction": np.round(RELIGHT_DIRECTION, 6).tolist(), "ambient": RELIGHT_AMBIENT,
                    "range": list(RELIGHT_RANGE)},
        "fields": fields,
        "supported": list(head.rig.supported),
        "pivot": np.round(renderer.pivot, 3).tolist(),
        "photo": {"width": head.width, "height": head.height, "texture": PHOTO_TEXTURE_PATH,
                  "background": PHOTO_BACKGROUND_PATH, "camera_px": head.scale * CAMERA_DISTANCE_CM,
                  "depth_px": head.scale * 60.0, "mouth_bias_px": head.scale * MOUTH_DEPTH_BIAS_CM,
                  "inside_softness_px": INSIDE_SOFTNESS_PX},
        "background": list(view.BACKGROUND),
        "lights": {"directions": view.light_directions().tolist(), "key": view.KEY, "fill": view.FILL,
                   "ambient": view.AMBIENT, "specular": view.SPECULAR, "shininess": 2 ** view.SHININESS_DOUBLINGS},
        "rig_vertices": n_rig,
    }


def photo_images(head) -> dict[str, tuple[bytes, str]]:
    """The photo and its filled background by the paths :func:`photo_model_document` names, each with its
    content type: the head's texture (the photo, the eyeballs' pictures below it) as PNG whose alpha is the
    person's coverage (round the outline the page's background shows through, as on the CPU), the background
    as JPEG."""
    import io

    from PIL import Image

    texture = head.texture_with_coverage()
    out = {}
    for path, image, kind in ((PHOTO_TEXTURE_PATH, texture, "PNG"), (PHOTO_BACKGROUND_PATH, head.background, "JPEG")):
        buffer = io.BytesIO()
        Image.fromarray(image).save(buffer, format=kind, **({"quality": 92} if kind == "JPEG" else {}))
        out[path] = (buffer.getvalue(), f"image/{kind.lower()}")
    return out
