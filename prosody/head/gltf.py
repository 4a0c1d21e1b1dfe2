"""The head as an animated glTF 2.0 binary (``.glb``), for Blender, three.js and game engines.

The file holds two meshes in one scene: the body (neck and shoulders, still) and the head, whose node turns
about the top of the spine. The head mesh carries one morph target per FAP it shows (named by the FAP's
MPEG-4 name in ``mesh.extras.targetNames``, as Blender and three.js read them): the target is the FAP's field
times :data:`TARGET_SCALE` of its unit (1024 units, the whole reference distance, for distances; 0.5 rad for
the eyeballs' angles), so a weight is the FAP value divided by that. One animation lasting the stream animates
the weights (LINEAR) and the head node's rotation (quaternions of R = Rz(roll) Ry(yaw) Rx(pitch)), one key per
frame at k / fps seconds. Units are metres (glTF's), +y up, the face looking along +z. Sound is not part of
glTF: add the recording in the player (docs/cli.md says how in Blender).
"""

from __future__ import annotations

import json
import os
import struct
from pathlib import Path

import numpy as np

from audio_features.atomic import atomic_write

from ..errors import FapWriteError
from ..fap.stream import FapStream
from ..fap.table import BY_NUMBER, HEAD_FAPS, RADIANS_PER_AU
from .mesh import NECK_PIVOT
from .rig import HeadRig, head_rig, rotation

#: A morph target is this many FAP units of its FAP (weight 1 = this value).
TARGET_SCALE = {"AU": 50_000.0, "default": 1024.0}
CM_PER_M = 100.0
_FLOAT, _UNSIGNED_INT = 5126, 5125
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
        component = _UNSIGNED_INT if array.dtype == np.uint32 else _FLOAT
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


def glb_document(stream: FapStream, *, rig: HeadRig | None = None) -> tuple[dict, bytes]:
    """The glTF JSON and binary chunk of the head animated by ``stream`` (see the module doc)."""
    rig = rig or head_rig()
    mesh = rig.mesh
    if stream.n_frames < 1:
        raise FapWriteError("a glTF animation needs at least one frame")
    head_part = mesh.rotates
    body_part = ~head_part
    buffer = _Buffer()
    pivot = np.asarray(NECK_PIVOT)
    from .render import HeadRenderer

    normals = HeadRenderer(16, 16, rig=rig).normals(mesh.vertices.astype(np.float64))

    def primitive(selected: np.ndarray, offset: np.ndarray, targets: list[np.ndarray] | None) -> dict:
        index = np.full(mesh.n_vertices, -1, np.int64)
        index[selected] = np.arange(int(selected.sum()))
        triangles = mesh.triangles[selected[mesh.triangles].all(axis=1)]
        positions = ((mesh.vertices[selected] - offset) / CM_PER_M).astype(np.float32)
        attributes = {"POSITION": buffer.add(positions, "VEC3", target=_ARRAY_BUFFER, bounds=True),
                      "NORMAL": buffer.add(normals[selected].astype(np.float32), "VEC3", target=_ARRAY_BUFFER),
                      "COLOR_0": buffer.add(mesh.colors[selected].astype(np.float32), "VEC3",
                                            target=_ARRAY_BUFFER)}
        out = {"attributes": attributes, "material": 0, "mode": 4,
               "indices": buffer.add(index[triangles].reshape(-1).astype(np.uint32), "SCALAR",
                                     target=_ELEMENT_ARRAY_BUFFER)}
        if targets:
            out["targets"] = [{"POSITION": buffer.add((t[selected] / CM_PER_M).astype(np.float32), "VEC3",
                                                      target=_ARRAY_BUFFER, bounds=True)} for t in targets]
        return out

    morph_faps = [f for f in rig.supported if f not in HEAD_FAPS and np.any(rig.fields[f - 1])]
    targets = [rig.fields[f - 1].astype(np.float64) * target_scale(f) for f in morph_faps]
    head_mesh = {"name": "head", "primitives": [primitive(head_part, pivot, targets)],
                 "weights": [0.0] * len(morph_faps),
                 "extras": {"targetNames": [BY_NUMBER[f].name for f in morph_faps]}}
    body_mesh = {"name": "body", "primitives": [primitive(body_part, np.zeros(3), None)]}

    values = np.where(stream.mask, np.nan_to_num(stream.values), 0.0)
    times = (np.arange(stream.n_frames) / stream.fps).astype(np.float32)
    weights = np.column_stack([values[:, f - 1] / target_scale(f) for f in morph_faps]).astype(np.float32)
    angles = values[:, [f - 1 for f in HEAD_FAPS]] * RADIANS_PER_AU
    quaternions = np.array([_quaternion(rotation(*row)) for row in angles], np.float32)
    time_accessor = buffer.add(times, "SCALAR", bounds=True)
    animation = {
        "name": stream.name or "speech",
        "samplers": [{"input": time_accessor, "interpolation": "LINEAR",
                      "output": buffer.add(weights.reshape(-1), "SCALAR")},
                     {"input": time_accessor, "interpolation": "LINEAR",
                      "output": buffer.add(quaternions, "VEC4")}],
        "channels": [{"sampler": 0, "target": {"node": 2, "path": "weights"}},
                     {"sampler": 1, "target": {"node": 1, "path": "rotation"}}],
    }
    document = {
        "asset": {"version": "2.0", "generator": "visual-prosody"},
        "scene": 0,
        "scenes": [{"name": "talking head", "nodes": [0, 1]}],
        "nodes": [{"name": "body", "mesh": 1},
                  {"name": "neck", "translation": (pivot / CM_PER_M).tolist(), "children": [2]},
                  {"name": "head", "mesh": 0}],
        "meshes": [head_mesh, body_mesh],
        "materials": [{"name": "skin", "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1],
                                                                "metallicFactor": 0.0, "roughnessFactor": 0.7}}],
        "animations": [animation],
        "accessors": buffer.accessors,
        "bufferViews": buffer.views,
        "buffers": [{"byteLength": len(buffer.data)}],
    }
    return document, bytes(buffer.data)


def write_glb(stream: FapStream, path: str | os.PathLike[str]) -> None:
    """Write the head animated by ``stream`` as a binary glTF 2.0 file (atomically)."""
    document, binary = glb_document(stream)
    text = json.dumps(document, separators=(",", ":")).encode("utf-8")
    text += b" " * (-len(text) % 4)
    binary += b"\0" * (-len(binary) % 4)
    total = 12 + 8 + len(text) + 8 + len(binary)
    with atomic_write(Path(path), mode="wb") as handle:
        handle.write(struct.pack("<4sII", b"glTF", 2, total))
        handle.write(struct.pack("<I4s", len(text), b"JSON") + text)
        handle.write(struct.pack("<I4s", len(binary), b"BIN\0") + binary)
