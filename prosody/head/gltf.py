"""The head as an animated glTF 2.0 binary (``.glb``), for Blender, three.js and game engines.

The file holds the head under a ``neck`` node at the top of the spine, whose rotation the animation turns
(quaternions of R = Rz(roll) Ry(yaw) Rx(pitch)), and what stays still: the body (neck and shoulders), or with
a photo (:mod:`.photo`) the person's hair, neck and shoulders as a mesh skinned to the neck (each vertex
following the head by its share) and the photo's background on a quad behind. The head carries morph
targets, one per FAP direction it shows (``NAME+`` and, for the two-way FAPs, ``NAME-``, MPEG-4's names, in
``mesh.extras.targetNames``), so that every weight the animation keys lies in 0..1: Blender's importer cuts
weights below 0. A target is the FAP's field times its units at weight 1 (``mesh.extras.targetUnits``:
1024 units, the whole reference distance, for distances; 50,000 AU for the eyeballs; or the stream's largest
value where that is larger). The animation keys the weights (LINEAR) and the neck's rotation at every frame,
at k / fps seconds.

Colours are glTF's: ``COLOR_0`` holds linear values (the renderers' display colours, converted). Triangles
are counter-clockwise seen from where they are seen; the mouth's inside, teeth and tongue use a double-sided
material. With a photo the face and the eyes carry ``TEXCOORD_0`` into the photo, their base colour texture.
Units are metres (glTF's), +y up, the face looking along +z (with a photo: the photo's own axes, its camera
looking along -z). Sound is not part of glTF: add the recording in the player (docs/cli.md says how in
Blender).
"""

from __future__ import annotations

import io
import json
import math
import os
import struct
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from audio_features.atomic import atomic_write

from ..errors import FapWriteError
from ..fap.fapfile import MAX_PLAYABLE_VALUE
from ..fap.stream import FapStream
from ..fap.table import BY_NUMBER, HEAD_FAPS, RADIANS_PER_AU
from .mesh import EYE_LEFT, EYE_RIGHT, FACE, LOWER_TEETH, MOUTH_INSIDE, NECK, NECK_PIVOT, SKULL, TONGUE, UPPER_TEETH
from .rig import HeadRig, head_rig, rotation

if TYPE_CHECKING:
    from .photo import PhotoHead

#: The head's parts drawn with the mouth's material (seen from both sides).
MOUTH_PARTS = (UPPER_TEETH, LOWER_TEETH, TONGUE, MOUTH_INSIDE)
#: How far the mouth's inside is set back in a .glb, in cm: a viewer has no depth bias to keep it behind the skin.
CAVITY_SETBACK_CM = 0.3
#: The largest FAP value written (the .fap writer's bound).
FAP_VALUE_LIMIT = float(MAX_PLAYABLE_VALUE)

#: A morph target is this many FAP units of its FAP (weight 1 = this value).
TARGET_SCALE = {"AU": 50_000.0, "default": 1024.0}
CM_PER_M = 100.0
_FLOAT, _UNSIGNED_INT, _UNSIGNED_BYTE = 5126, 5125, 5121
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963


def target_scale(fap: int) -> float:
    """FAP units per unit of morph weight for ``fap``."""
    return TARGET_SCALE["AU"] if BY_NUMBER[fap].fapu == "AU" else TARGET_SCALE["default"]


def _quaternion(matrix: np.ndarray) -> np.ndarray:
    """Unit quaternion (x, y, z, w) of a rotation matrix."""
    m = matrix
    w = np.sqrt(max(0.0, 1.0 + m[0, 0] + m[1, 1] + m[2, 2])) / 2
    x = np.sqrt(max(0.0, 1.0 + m[0, 0] - m[1, 1] - m[2, 2])) / 2
    y = np.sqrt(max(0.0, 1.0 - m[0, 0] + m[1, 1] - m[2, 2])) / 2
    z = np.sqrt(max(0.0, 1.0 - m[0, 0] - m[1, 1] + m[2, 2])) / 2
    x = np.copysign(x, m[2, 1] - m[1, 2])
    y = np.copysign(y, m[0, 2] - m[2, 0])
    z = np.copysign(z, m[1, 0] - m[0, 1])
    q = np.array([x, y, z, w])
    return q / np.linalg.norm(q)


class _Buffer:
    """The binary chunk and its views and accessors, built as data is added."""

    def __init__(self) -> None:
        self.data = bytearray()
        self.views: list[dict] = []
        self.accessors: list[dict] = []

    def add(self, array: np.ndarray, kind: str, *, target: int | None = None, bounds: bool = False) -> int:
        array = np.ascontiguousarray(array)
        component = {np.dtype(np.uint32): _UNSIGNED_INT, np.dtype(np.uint8): _UNSIGNED_BYTE}.get(array.dtype, _FLOAT)
        while len(self.data) % 4:
            self.data.append(0)
        view = {"buffer": 0, "byteOffset": len(self.data), "byteLength": array.nbytes}
        if target is not None:
            view["target"] = target
        self.data += array.tobytes()
        self.views.append(view)
        count = array.shape[0] if kind != "SCALAR" or array.ndim == 1 else array.size
        accessor = {"bufferView": len(self.views) - 1, "componentType": component, "count": int(count),
                    "type": kind}
        if bounds:
            flat = array.reshape(count, -1)
            accessor["min"] = flat.min(axis=0).tolist()
            accessor["max"] = flat.max(axis=0).tolist()
        self.accessors.append(accessor)
        return len(self.accessors) - 1


def srgb_to_linear(colors: np.ndarray) -> np.ndarray:
    """Display (sRGB) colours 0..1 -> linear ones, as glTF's ``COLOR_0`` and base colours are defined.

    Examples
    --------
    >>> srgb_to_linear(np.array([0.0, 0.04045, 0.5, 1.0])).round(4).tolist()
    [0.0, 0.0031, 0.214, 1.0]
    """
    c = np.clip(np.asarray(colors, float), 0.0, 1.0)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def morph_targets(rig: HeadRig, stream: FapStream) -> list[tuple[int, int, str, float]]:
    """The morph targets: (FAP, sign, name, FAP units at weight 1) for each FAP the head shows (but the
    head's turns), one per direction it moves, so that every weight is in 0..1 (Blender's importer cuts
    weights below 0): ``NAME+`` its positive direction, ``NAME-`` the negative one, for the two-way FAPs
    and any FAP the stream moves below 0. Weight 1 is :func:`target_scale` units, or the stream's largest
    value where that is larger."""
    values = np.where(stream.mask, np.nan_to_num(stream.values), 0.0)
    targets = []
    for fap in rig.supported:
        if fap in HEAD_FAPS or not np.any(rig.fields[fap - 1]):
            continue
        curve = values[:, fap - 1]
        for sign in (1, -1):
            if sign < 0 and BY_NUMBER[fap].direction != "B" and not (curve < 0).any():
                continue
            reach = float(np.max(sign * curve, initial=0.0))
            scale = max(target_scale(fap), math.ceil(reach))
            targets.append((fap, sign, f"{BY_NUMBER[fap].name}{'+' if sign > 0 else '-'}", scale))
    return targets


def _image_bytes(image: np.ndarray) -> tuple[bytes, str]:
    """An image as JPEG, or as PNG where it has an alpha channel; with its MIME type."""
    from PIL import Image

    out = io.BytesIO()
    if image.ndim == 3 and image.shape[2] == 4:
        Image.fromarray(image).save(out, format="PNG")
        return out.getvalue(), "image/png"
    Image.fromarray(image).save(out, format="JPEG", quality=92)
    return out.getvalue(), "image/jpeg"


def glb_document(stream: FapStream, *, rig: HeadRig | None = None, photo: PhotoHead | None = None
                 ) -> tuple[dict, bytes]:
    """The glTF JSON and binary chunk of the head animated by ``stream`` (see the module doc); with
    ``photo``, that person's head, textured by the photo, with the person and the background behind."""
    if photo is not None:
        rig = photo.rig
    rig = rig or head_rig()
    mesh = rig.mesh
    if stream.n_frames < 1:
        raise FapWriteError("a glTF animation needs at least one frame")
    values = np.where(stream.mask, np.nan_to_num(stream.values), 0.0)
    if not np.isfinite(values).all() or np.abs(values).max(initial=0.0) > FAP_VALUE_LIMIT:
        raise FapWriteError(f"a glTF head takes FAP values within +-{FAP_VALUE_LIMIT:g} (as a .fap file does); "
                            f"this stream holds {np.abs(values).max():.4g}")
    buffer = _Buffer()
    if photo is None:
        turn, shift = np.eye(3), np.zeros(3)
    else:  # the photo's axes (x right, y up, z towards the camera), at the head's size: the photo's framing
        turn, shift = photo.rotation, photo.offset / photo.scale
    pivot = np.asarray(NECK_PIVOT) @ turn.T + shift

    def place(points: np.ndarray) -> np.ndarray:
        return np.asarray(points, float) @ turn.T + shift

    from .render import HeadRenderer

    normals = HeadRenderer(16, 16, rig=rig).normals(mesh.vertices.astype(np.float64)) @ turn.T
    head_part = mesh.rotates.copy()  # the neck, bending, is in the skinned body
    if photo is not None:  # the photo's own hair, neck and shoulders stand for the skull and the body
        head_part &= ~np.isin(mesh.part, (SKULL, NECK))
    targets = morph_targets(rig, stream)
    fields = [sign * rig.fields[fap - 1].astype(np.float64) @ turn.T * scale for fap, sign, _, scale in targets]
    colors = srgb_to_linear(mesh.colors)
    textured = np.isin(mesh.part, (FACE, EYE_LEFT, EYE_RIGHT)) if photo is not None else np.zeros(len(colors), bool)
    colors[textured] = 1.0
    mouth = np.isin(mesh.part, MOUTH_PARTS)
    # the mouth's dark inside set back a little: the CPU renderers draw it behind the skin by a depth bias,
    # which a glTF cannot carry, and where it runs close under the skin below the corners it came through
    setback = np.zeros((mesh.n_vertices, 3))
    setback[mesh.part == MOUTH_INSIDE, 2] = -CAVITY_SETBACK_CM

    def primitive(selected: np.ndarray, offset: np.ndarray, material: int, with_targets: bool) -> dict:
        index = np.full(mesh.n_vertices, -1, np.int64)
        index[selected] = np.arange(int(selected.sum()))
        triangles = mesh.triangles[selected[mesh.triangles].all(axis=1)]
        positions = ((place(mesh.vertices[selected] + setback[selected]) - offset) / CM_PER_M).astype(np.float32)
        attributes = {"POSITION": buffer.add(positions, "VEC3", target=_ARRAY_BUFFER, bounds=True),
                      "NORMAL": buffer.add(normals[selected].astype(np.float32), "VEC3", target=_ARRAY_BUFFER),
                      "COLOR_0": buffer.add(colors[selected].astype(np.float32), "VEC3", target=_ARRAY_BUFFER)}
        if photo is not None and material == 0:
            uv = photo.uv[selected] / np.array(photo.texture_size)
            attributes["TEXCOORD_0"] = buffer.add(uv.astype(np.float32), "VEC2", target=_ARRAY_BUFFER)
        out = {"attributes": attributes, "material": material, "mode": 4,
               "indices": buffer.add(index[triangles].reshape(-1).astype(np.uint32), "SCALAR",
                                     target=_ELEMENT_ARRAY_BUFFER)}
        if with_targets and fields:
            out["targets"] = [{"POSITION": buffer.add((f[selected] / CM_PER_M).astype(np.float32), "VEC3",
                                                      target=_ARRAY_BUFFER, bounds=True)} for f in fields]
        return out

    head_mesh = {"name": "head", "primitives": [primitive(head_part & ~mouth, pivot, 0, True),
                                                 primitive(head_part & mouth, pivot, 1, True)],
                 "weights": [0.0] * len(targets),
                 "extras": {"targetNames": [name for _, _, name, _ in targets],
                            "targetUnits": [scale for _, _, _, scale in targets]}}
    meshes = [head_mesh]
    materials = _materials(photo is not None)
    # the joints: "body" (still) and "neck" (turned by the animation), the head's mesh under the neck; what
    # stays, or bends with the neck, is a mesh skinned to the two
    nodes = [{"name": "body", "children": [1]},
             {"name": "neck", "translation": (pivot / CM_PER_M).tolist(), "children": [2]},
             {"name": "head", "mesh": 0}]
    binds = np.stack([np.eye(4), np.eye(4)])
    binds[1, :3, 3] = -pivot / CM_PER_M
    skins = [{"name": "neck bends", "joints": [0, 1],
              "inverseBindMatrices": buffer.add(binds.transpose(0, 2, 1).reshape(2, 16).astype(np.float32),
                                                "MAT4")}]
    if photo is None:
        body = ~head_part
        still = primitive(body, np.zeros(3), 0, False)
        joints, weights = _skin_weights(mesh.turn_share()[body])
        still["attributes"].update(JOINTS_0=buffer.add(joints, "VEC4", target=_ARRAY_BUFFER),
                                   WEIGHTS_0=buffer.add(weights, "VEC4", target=_ARRAY_BUFFER))
        meshes.append({"name": "body", "primitives": [still]})
        nodes.append({"name": "neck and shoulders", "mesh": 1, "skin": 0})
        scene_nodes, images = [0, 3], []
    else:
        meshes += _photo_meshes(photo, buffer, place, pivot)
        nodes += [{"name": "person", "mesh": 1, "skin": 0}, {"name": "backdrop", "mesh": 2}]
        scene_nodes = [0, 3, 4]
        # the person's texture carries its coverage as alpha: round the outline the backdrop shows (MASK); its
        # colours there are the person's, without the background's (the texture's photo part)
        person = photo.texture_with_coverage()[:photo.height, :photo.width]
        images = [_image_bytes(photo.texture), _image_bytes(photo.background), _image_bytes(person)]

    animation = _animation(stream, values, targets, buffer)
    image_entries = [_embed(buffer, *image) for image in images]
    document = {
        "asset": {"version": "2.0", "generator": "visual-prosody"},
        "scene": 0,
        "scenes": [{"name": "talking head", "nodes": scene_nodes}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "animations": [animation],
        "accessors": buffer.accessors,
        "bufferViews": buffer.views,
        "buffers": [{"byteLength": len(buffer.data)}],
    }
    if image_entries:
        document.update(images=image_entries, samplers=[{"magFilter": 9729, "minFilter": 9729}],
                        textures=[{"source": k, "sampler": 0} for k in range(len(image_entries))],
                        extensionsUsed=["KHR_materials_unlit"])
    if skins:
        document["skins"] = skins
    return document, bytes(buffer.data)


def _materials(photo: bool) -> list[dict]:
    """The head's skin (or the photo, unlit: it is lit as it was taken) and the mouth (double-sided); with a
    photo, the person's and the background's materials (unlit, textures 2 and 1: the person's is the photo
    with its coverage as alpha, cut at one half, so no strip of background turns with the head)."""
    def material(name: str, roughness: float, **more) -> dict:
        return {"name": name, **more, "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1], "metallicFactor": 0.0,
                                                               "roughnessFactor": roughness}}

    unlit: dict[str, dict] = {"KHR_materials_unlit": {}}
    if not photo:
        return [material("skin", 0.7), material("mouth", 0.6, doubleSided=True)]
    materials = [material("photo", 1.0, extensions=unlit), material("mouth", 0.6, doubleSided=True),
                 material("person", 1.0, extensions=unlit), material("background", 1.0, extensions=unlit)]
    for entry, texture in zip((materials[0], materials[2], materials[3]), (0, 2, 1), strict=True):
        entry["pbrMetallicRoughness"]["baseColorTexture"] = {"index": texture}
    materials[2].update(alphaMode="MASK", alphaCutoff=0.5)
    return materials


def _animation(stream: FapStream, values: np.ndarray, targets: list[tuple[int, int, str, float]],
               buffer: _Buffer) -> dict:
    """The one animation: the morph weights (node 2) and the neck's rotation (node 1) at every frame."""
    times = (np.arange(stream.n_frames) / stream.fps).astype(np.float32)
    weights = np.column_stack([np.clip(sign * values[:, fap - 1] / scale, 0.0, 1.0)
                               for fap, sign, _, scale in targets]).astype(np.float32)
    angles = values[:, [f - 1 for f in HEAD_FAPS]] * RADIANS_PER_AU
    quaternions = np.array([_quaternion(rotation(*row)) for row in angles], np.float32)
    time_accessor = buffer.add(times, "SCALAR", bounds=True)
    return {
        "name": stream.name or "speech",
        "samplers": [{"input": time_accessor, "interpolation": "LINEAR",
                      "output": buffer.add(weights.reshape(-1), "SCALAR")},
                     {"input": time_accessor, "interpolation": "LINEAR",
                      "output": buffer.add(quaternions, "VEC4")}],
        "channels": [{"sampler": 0, "target": {"node": 2, "path": "weights"}},
                     {"sampler": 1, "target": {"node": 1, "path": "rotation"}}],
    }


def _skin_weights(share: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``JOINTS_0`` and ``WEIGHTS_0`` of vertices following the neck joint (1) by ``share``, the body joint (0)
    by the rest: the larger share first, a joint of no weight written as 0 (glTF's rule)."""
    share = np.clip(np.asarray(share, float), 0.0, 1.0)
    neck_first = share > 0.5
    joints = np.zeros((len(share), 4), np.uint8)
    weights = np.zeros((len(share), 4), np.float32)
    joints[:, 0] = neck_first
    weights[:, 0] = np.where(neck_first, share, 1.0 - share)
    weights[:, 1] = 1.0 - weights[:, 0]
    joints[:, 1] = np.where(weights[:, 1] > 0, ~neck_first, 0)
    return joints, weights


def _embed(buffer: _Buffer, data: bytes, mime_type: str) -> dict:
    """An image in the binary chunk (JPEG or PNG), as a glTF image entry."""
    while len(buffer.data) % 4:
        buffer.data.append(0)
    buffer.views.append({"buffer": 0, "byteOffset": len(buffer.data), "byteLength": len(data)})
    buffer.data += data
    return {"bufferView": len(buffer.views) - 1, "mimeType": mime_type}


def _photo_meshes(photo: PhotoHead, buffer: _Buffer, place, pivot: np.ndarray) -> list[dict]:
    """The person (skinned: the head's share of each vertex follows the neck joint) and the background, a
    quad behind the person at the photo's framing."""
    layer = place(photo.layer_vertices)
    uv = photo.layer_uv / np.array([photo.width, photo.height])
    weight = np.clip(photo.layer_weight, 0.0, 1.0)
    joints, weights = _skin_weights(weight)
    triangles = photo.layer_triangles
    corners = layer[triangles]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    if np.median(normal[:, 2]) < 0:  # counter-clockwise seen from the camera
        triangles = triangles[:, ::-1]
    person = {"attributes": {
        "POSITION": buffer.add((layer / CM_PER_M).astype(np.float32), "VEC3", target=_ARRAY_BUFFER, bounds=True),
        "TEXCOORD_0": buffer.add(uv.astype(np.float32), "VEC2", target=_ARRAY_BUFFER),
        "JOINTS_0": buffer.add(joints, "VEC4", target=_ARRAY_BUFFER),
        "WEIGHTS_0": buffer.add(weights, "VEC4", target=_ARRAY_BUFFER)},
        "indices": buffer.add(triangles.reshape(-1).astype(np.uint32), "SCALAR", target=_ELEMENT_ARRAY_BUFFER),
        "material": 2, "mode": 4}
    # the background: the photo's rectangle, 25 cm behind the head's origin (in the photo's axes)
    w, h = photo.width / photo.scale, photo.height / photo.scale
    depth = -25.0
    quad = np.array([[0.0, 0.0, depth], [w, 0.0, depth], [w, -h, depth], [0.0, -h, depth]])
    backdrop = {"attributes": {
        "POSITION": buffer.add((quad / CM_PER_M).astype(np.float32), "VEC3", target=_ARRAY_BUFFER, bounds=True),
        "TEXCOORD_0": buffer.add(np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32), "VEC2",
                                 target=_ARRAY_BUFFER)},
        "indices": buffer.add(np.array([0, 2, 1, 0, 3, 2], np.uint32), "SCALAR", target=_ELEMENT_ARRAY_BUFFER),
        "material": 3, "mode": 4}
    return [{"name": "person", "primitives": [person]}, {"name": "backdrop", "primitives": [backdrop]}]


def write_glb(stream: FapStream, path: str | os.PathLike[str], *, photo: PhotoHead | None = None) -> None:
    """Write the head animated by ``stream`` as a binary glTF 2.0 file (atomically); with ``photo``, the
    head of the person in it (:func:`prosody.head.photo.photo_head`)."""
    document, binary = glb_document(stream, photo=photo)
    text = json.dumps(document, separators=(",", ":")).encode("utf-8")
    text += b" " * (-len(text) % 4)
    binary += b"\0" * (-len(binary) % 4)
    total = 12 + 8 + len(text) + 8 + len(binary)
    with atomic_write(Path(path), mode="wb") as handle:
        handle.write(struct.pack("<4sII", b"glTF", 2, total))
        handle.write(struct.pack("<I4s", len(text), b"JSON") + text)
        handle.write(struct.pack("<I4s", len(binary), b"BIN\0") + binary)
