"""Writers and readers of FAP streams in the formats other tools read (stream in, file out); the registry that
chooses a writer by name or file ending is :mod:`prosody.outputs`.

Formats and their mapping from FAP units (docs/fap.md; AU = 1e-5 rad, ENS = eye-nose separation / 1024):

- ``fap``: MPEG-4 FAP text (:mod:`prosody.fap.fapfile`).
- ``csv``: ``frame,time_s`` then one column per active FAP, named ``fap<N>_<name>_<unit>``, in FAP units
  (``au``, ``ens``, ...), or with ``physical=True`` in radians (``rad``) and fractions of the reference
  distance (``ens0``, ...). A cell is empty where the FAP is masked off in that frame.
- ``json``: ``{"format": "visual-prosody-faps", "version": 1, "name", "fps", "frames", "faps": [{"fap", "name",
  "unit", "values": [value or null per frame]}]}`` in FAP units.
- ``bvh``: one ``Head`` joint (BVH's Y-up, character facing +Z, X to the character's left) with channels
  ``Zrotation Yrotation Xrotation`` in degrees: Xrotation = head pitch (FAP 48, + bows down), Yrotation = head
  yaw (FAP 49, + turns to the character's left), Zrotation = head roll (FAP 50, + tilts to the character's
  right); the order composes R = Rz Ry Rx as the recorded head motion does (docs/dependencies.md). Brows are not in BVH.
- ``rhubarb-tsv``, ``rhubarb-json``, ``rhubarb-xml``, ``moho-dat``, ``prestonblair-dat``: the lips as Rhubarb
  Lip Sync's mouth cues (A-H, X) in its files (``.rhubarb.tsv``, ``.rhubarb.json``, ``.rhubarb.xml``, ``.dat``,
  ``.prestonblair.dat``; :mod:`prosody.fap.mouth_cues`).
- ``livelink``: Live Link Face style CSV (``*.livelink.csv``): ``Timecode,BlendShapeCount`` then the 52 ARKit
  blendshape columns and ``HeadYaw,HeadPitch,HeadRoll`` plus the six eye angles. Head angles in radians with
  the FAPs' signs (HeadYaw + to the character's left, HeadPitch + down, HeadRoll + to its right); BrowInnerUp is
  the mean of FAP 31/32 and BrowOuterUpLeft/Right are FAP 35/36 (or the middle brows 33/34 when the outer ones
  are absent), divided by ``BROW_FULL_SCALE_ENS`` and clipped to [0, 1]. The mouth and the rest of the face,
  each weight a FAP (or a sum of FAPs) over the full scale in :data:`LIVELINK_FULL_SCALE`, clipped to [0, 1]:
  JawOpen = FAP 3; MouthClose = the jaw's opening not matched by the lips' (FAP 3 minus the inner-lip opening
  FAP 3 - 4 - 5); MouthPucker and MouthFunnel share the protrusion (FAP 16, 17) by how open the lips are
  (closed: pucker, open: funnel); MouthSmile = FAP 12/13 up, MouthFrown = down; MouthStretch = FAP 6/7 outwards;
  MouthPress = the mid lips pressed together beyond rest (FAP 4 + 5 > 0); MouthUpperUp = FAP 8/9 up,
  MouthLowerDown = FAP 10/11 down; CheekSquint = FAP 41/42; EyeBlink = FAP 19/20 down, EyeWide = up; BrowDown =
  FAP 31/32 down; NoseSneer = FAP 63. Every other column is 0.
"""

from __future__ import annotations

import csv
import json
import math
import os
from pathlib import Path

import numpy as np

from audio_features.atomic import atomic_write

from ..errors import ConfigError, FapWriteError
from .stream import FapStream
from .table import BY_NUMBER, HEAD_FAPS, RADIANS_PER_AU

#: Brow raise (ENS) written as a full blendshape weight of 1 in Live Link Face CSV: about the largest raise
#: the eyebrow rule makes with its default gain (0.1 ENS/Hz x 450 Hz - 5 = 40 ENS).
BROW_FULL_SCALE_ENS = 40.0
#: FAP values written as a Live Link blendshape weight of 1 (each in its FAP's unit; about the largest the
#: visemes and expressions make): the jaw 600 MNS (12 mm), lip and corner motion 150, protrusion 300 MNS,
#: eyelids 300 IRISD, cheeks 150 ENS, brows lowered 150 ENS, nose 80 ENS.
LIVELINK_FULL_SCALE = {"jaw": 600.0, "lip": 150.0, "protrusion": 300.0, "press": 60.0, "eyelid": 300.0,
                       "cheek": 150.0, "brow_down": 150.0, "nose": 80.0}
ARKIT_BLENDSHAPES = (
    "EyeBlinkLeft", "EyeLookDownLeft", "EyeLookInLeft", "EyeLookOutLeft", "EyeLookUpLeft", "EyeSquintLeft",
    "EyeWideLeft", "EyeBlinkRight", "EyeLookDownRight", "EyeLookInRight", "EyeLookOutRight", "EyeLookUpRight",
    "EyeSquintRight", "EyeWideRight", "JawForward", "JawRight", "JawLeft", "JawOpen", "MouthClose",
    "MouthFunnel", "MouthPucker", "MouthRight", "MouthLeft", "MouthSmileLeft", "MouthSmileRight",
    "MouthFrownLeft", "MouthFrownRight", "MouthDimpleLeft", "MouthDimpleRight", "MouthStretchLeft",
    "MouthStretchRight", "MouthRollLower", "MouthRollUpper", "MouthShrugLower", "MouthShrugUpper",
    "MouthPressLeft", "MouthPressRight", "MouthLowerDownLeft", "MouthLowerDownRight", "MouthUpperUpLeft",
    "MouthUpperUpRight", "BrowDownLeft", "BrowDownRight", "BrowInnerUp", "BrowOuterUpLeft", "BrowOuterUpRight",
    "CheekPuff", "CheekSquintLeft", "CheekSquintRight", "NoseSneerLeft", "NoseSneerRight", "TongueOut",
)
LIVELINK_ROTATIONS = ("HeadYaw", "HeadPitch", "HeadRoll", "LeftEyeYaw", "LeftEyePitch", "LeftEyeRoll",
                      "RightEyeYaw", "RightEyePitch", "RightEyeRoll")


def _number(value: float) -> str:
    return f"{value:.6g}"


def csv_columns(stream: FapStream, *, physical: bool = False) -> list[str]:
    """Column names of the CSV export: ``frame,time_s,fap<N>_<name>_<unit>...``."""
    names = ["frame", "time_s"]
    for fap in stream.active_faps:
        info = BY_NUMBER[fap]
        unit = info.physical_unit if physical else info.fapu
        names.append(f"fap{fap}_{info.name}_{unit.lower()}")
    return names


def write_csv(stream: FapStream, path: str | os.PathLike[str], *, physical: bool = False) -> None:
    """One row per frame: frame, time in s, and each active FAP (empty where masked off)."""
    active = stream.active_faps
    values = stream.to_physical() if physical else np.where(stream.mask, stream.values, np.nan)
    with atomic_write(path) as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(csv_columns(stream, physical=physical))
        for k in range(stream.n_frames):
            row = [str(k), f"{k / stream.fps:.6f}"]
            row += ["" if np.isnan(values[k, fap - 1]) else _number(values[k, fap - 1]) for fap in active]
            writer.writerow(row)


def write_json(stream: FapStream, path: str | os.PathLike[str]) -> None:
    """Frames, fps, and per active FAP its number, name, unit and values (null where masked off)."""
    faps = []
    for fap in stream.active_faps:
        column = stream.values[:, fap - 1]
        active = stream.mask[:, fap - 1]
        faps.append({"fap": fap, "name": BY_NUMBER[fap].name, "unit": BY_NUMBER[fap].fapu,
                     "values": [float(v) if on else None for v, on in zip(column.tolist(), active.tolist(),
                                                                        strict=True)]})
    payload = {"format": "visual-prosody-faps", "version": 1, "name": stream.name, "fps": stream.fps,
               "frames": stream.n_frames, "faps": faps}
    with atomic_write(path, newline="\n") as handle:
        json.dump(payload, handle, allow_nan=False)
        handle.write("\n")


#: Largest JSON or JSON-lines stream read back (a 2-hour stream with lips is about 300 MB as JSON).
MAX_JSON_BYTES = 1 << 30


#: The longest stream name read from a JSON file (a .fap header line is bounded as much).
MAX_NAME_CHARACTERS = 1000


def _frame_rate(fps: float) -> float:
    """A stream file's frame rate, within the rates a face plays (as a .fap file's)."""
    from .fapfile import FPS_RANGE

    if not (math.isfinite(fps) and FPS_RANGE[0] <= fps <= FPS_RANGE[1]):
        raise ValueError(f"its frame rate {fps:g} fps is outside {FPS_RANGE[0]:g}-{FPS_RANGE[1]:g} fps")
    return fps


#: The file endings of the streams :func:`read_stream` reads back.
STREAM_ENDINGS = (".fap", ".json", ".jsonl")


def is_stream_file(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` names a stream :func:`read_stream` reads (by its ending), not a recording.

    Parameters
    ----------
    path : path

    Returns
    -------
    bool
    """
    return Path(path).suffix.lower() in STREAM_ENDINGS


def read_stream(path: str | os.PathLike[str]) -> FapStream:
    """A FAP stream from a file, whatever this package reads: a ``.fap`` (any player's; see
    :func:`prosody.fap.fapfile.read_fap`), the ``json`` export or the JSON lines of ``prosody stream``
    (:func:`read_stream_json`).

    Parameters
    ----------
    path : path
        A file ending in one of :data:`STREAM_ENDINGS`.

    Returns
    -------
    FapStream

    Raises
    ------
    ConfigError
        Another ending: a ``.csv`` export is not read back.
    FapFormatError
        A file of its ending that is not such a stream.
    """
    ending = Path(path).suffix.lower()
    if ending == ".fap":
        from .fapfile import read_fap

        return read_fap(path).stream
    if ending in (".json", ".jsonl"):
        return read_stream_json(path)
    raise ConfigError(f"{path}: not a stream this package reads back ({', '.join(STREAM_ENDINGS)}); a .csv export "
                      "is not read back (convert to .json)")


def read_stream_json(path: str | os.PathLike[str]) -> FapStream:
    """Read back a stream this package wrote: the ``json`` export, or the JSON lines of ``prosody stream``
    (``{"frame", "time_s", "faps": {"<n>": value}}`` per line, frame rate from the times).

    Raises
    ------
    FapFormatError
        Not such a file (the message names the file and, for JSON lines, the line).
    """
    from audio_features.inputs import open_input

    from ..errors import FapFormatError

    name = str(path)
    try:
        with open_input(path, text=True, encoding="utf-8-sig", max_bytes=MAX_JSON_BYTES) as handle:
            text = handle.read()
    except (OSError, UnicodeDecodeError) as error:
        raise FapFormatError(name, None, f"cannot be read ({getattr(error, 'strerror', None) or error})") from None
    try:
        if name.lower().endswith(".jsonl"):
            rows = [json.loads(line) for line in text.splitlines() if line.strip()]
            if not rows:
                raise ValueError("no frames")
            times = np.array([float(row["time_s"]) for row in rows])
            step = float(np.median(np.diff(times))) if len(rows) > 1 else 1 / 30
            if not (math.isfinite(step) and step > 0):
                raise ValueError("its frames' time_s do not increase")
            fps = _frame_rate(round(1 / step, 3))
            faps = sorted({int(fap) for row in rows for fap in row["faps"]})
            curves = {fap: np.array([float(row["faps"].get(str(fap), 0.0)) for row in rows]) for fap in faps}
            return FapStream.from_curves(curves, fps=fps, name=Path(name).stem, n_frames=len(rows))
        payload = json.loads(text)
        if payload.get("format") != "visual-prosody-faps":
            raise ValueError("not a visual-prosody-faps JSON file")
        n = int(payload["frames"])
        curves = {int(entry["fap"]): np.array([0.0 if v is None else float(v) for v in entry["values"]])
                  for entry in payload["faps"]}
        stream_name = str(payload.get("name", ""))
        if len(stream_name) > MAX_NAME_CHARACTERS:
            raise ValueError(f"its name has {len(stream_name)} characters (at most {MAX_NAME_CHARACTERS})")
        return FapStream.from_curves(curves, fps=_frame_rate(float(payload["fps"])), name=stream_name, n_frames=n)
    except (ValueError, KeyError, TypeError, AttributeError, RecursionError, ConfigError) as error:
        raise FapFormatError(name, None, f"not a stream this package wrote ({error})") from None


def _degrees(stream: FapStream, fap: int) -> np.ndarray:
    return np.degrees(stream.curve(fap) * RADIANS_PER_AU)


def write_bvh(stream: FapStream, path: str | os.PathLike[str]) -> None:
    """A one-joint BVH: the head's rotation in degrees (see the module docstring for axes and signs)."""
    if not any(stream.mask[:, fap - 1].any() for fap in HEAD_FAPS):
        raise FapWriteError("the stream has no head rotation (FAP 48-50) to write as BVH")
    pitch, yaw, roll = (_degrees(stream, fap) for fap in HEAD_FAPS)
    lines = ["HIERARCHY", "ROOT Head", "{", "\tOFFSET 0.0 0.0 0.0",
             "\tCHANNELS 3 Zrotation Yrotation Xrotation", "\tEnd Site", "\t{", "\t\tOFFSET 0.0 20.0 0.0", "\t}",
             "}", "MOTION", f"Frames: {stream.n_frames}", f"Frame Time: {1 / stream.fps:.8f}"]
    lines += [f"{z:.5f} {y:.5f} {x:.5f}" for z, y, x in zip(roll, yaw, pitch, strict=True)]
    with atomic_write(path, newline="\n") as handle:
        handle.write("\n".join(lines) + "\n")


def livelink_timecode(frame: int, fps: float) -> str:
    """``HH:MM:SS:FF.mmm`` of a frame (FF the frame within the second, .mmm its fraction)."""
    seconds, within = divmod(frame, fps)
    hours, rest = divmod(int(seconds), 3600)
    minutes, secs = divmod(rest, 60)
    whole = int(within)
    return f"{hours:02d}:{minutes:02d}:{secs:02d}:{whole:02d}.{int(round((within - whole) * 1000)):03d}"


def write_livelink(stream: FapStream, path: str | os.PathLike[str]) -> None:
    """Live Link Face style CSV (see the module docstring for the mapping)."""
    columns = livelink_columns(stream)
    with atomic_write(path) as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(["Timecode", "BlendShapeCount", *columns])
        for k in range(stream.n_frames):
            writer.writerow([livelink_timecode(k, stream.fps), len(columns),
                             *(_number(values[k]) for values in columns.values())])


def livelink_columns(stream: FapStream) -> dict[str, np.ndarray]:
    """The 52 ARKit blendshape weights and 9 Live Link rotations (radians) of every frame, in the order of
    Live Link Face's CSV (see the module docstring for the mapping)."""
    n = stream.n_frames
    columns = {name: np.zeros(n) for name in (*ARKIT_BLENDSHAPES, *LIVELINK_ROTATIONS)}

    def brow(faps: tuple[int, ...]) -> np.ndarray:
        present = [fap for fap in faps if stream.mask[:, fap - 1].any()]
        if not present:
            return np.zeros(n)
        return np.clip(np.mean([stream.curve(fap) for fap in present], axis=0) / BROW_FULL_SCALE_ENS, 0.0, 1.0)

    columns["BrowInnerUp"] = brow((31, 32))
    columns["BrowOuterUpLeft"] = brow((35,)) if stream.mask[:, 34].any() else brow((33,))
    columns["BrowOuterUpRight"] = brow((36,)) if stream.mask[:, 35].any() else brow((34,))
    for name, fap in (("HeadYaw", 49), ("HeadPitch", 48), ("HeadRoll", 50)):
        columns[name] = stream.curve(fap) * RADIANS_PER_AU
    columns.update(_livelink_face(stream))
    return columns


def _livelink_face(stream: FapStream) -> dict[str, np.ndarray]:
    """The mouth, eyelid, cheek, lowered-brow and nose blendshapes of a stream (see the module docstring)."""
    scale = LIVELINK_FULL_SCALE
    fap = stream.curve  # 0 where masked off: neutral

    def weight(values: np.ndarray, full: float) -> np.ndarray:
        return np.clip(values / full, 0.0, 1.0)

    opening = fap(3) - fap(4) - fap(5)
    protrusion = (fap(16) + fap(17)) / 2
    open_share = weight(opening, scale["jaw"] / 2)
    out = {"JawOpen": weight(fap(3), scale["jaw"]), "MouthClose": weight(fap(3) - opening, scale["jaw"]),
           "MouthPucker": weight(protrusion, scale["protrusion"]) * (1 - open_share),
           "MouthFunnel": weight(protrusion, scale["protrusion"]) * open_share,
           "NoseSneerLeft": weight(fap(63), scale["nose"]), "NoseSneerRight": weight(fap(63), scale["nose"])}
    for side, corner, stretch, upper, lower, eyelid, cheek, brow in (
            ("Left", 12, 6, 8, 10, 19, 41, 31), ("Right", 13, 7, 9, 11, 20, 42, 32)):
        out[f"MouthSmile{side}"] = weight(fap(corner), scale["lip"])
        out[f"MouthFrown{side}"] = weight(-fap(corner), scale["lip"])
        out[f"MouthStretch{side}"] = weight(fap(stretch), scale["lip"])
        out[f"MouthPress{side}"] = weight(fap(4) + fap(5), scale["press"])
        out[f"MouthUpperUp{side}"] = weight(-fap(upper), scale["lip"])
        out[f"MouthLowerDown{side}"] = weight(-fap(lower), scale["lip"])
        out[f"EyeBlink{side}"] = weight(fap(eyelid), scale["eyelid"])
        out[f"EyeWide{side}"] = weight(-fap(eyelid), scale["eyelid"] / 2)
        out[f"CheekSquint{side}"] = weight(fap(cheek), scale["cheek"])
        out[f"BrowDown{side}"] = weight(-fap(brow), scale["brow_down"])
    return out
