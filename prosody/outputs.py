"""Every output format by name and file ending, and the one writer that chooses among them (stream in, file
out): the FAP formats (:mod:`prosody.fap.fapfile`, :mod:`prosody.fap.exporters`), Rhubarb Lip Sync's mouth
cues (:mod:`prosody.fap.mouth_cues`) and the 3D head (:mod:`prosody.head.gltf`).

It sits above the formats it dispatches to, so none of them reaches up to another's layer. See
:mod:`prosody.fap.exporters` for what each format holds.

Examples
--------
>>> format_for("talk.rhubarb.tsv"), format_for("talk.livelink.csv"), format_for("talk.glb")
('rhubarb-tsv', 'livelink', 'gltf')
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from .errors import ConfigError
from .fap.exporters import write_bvh, write_csv, write_json, write_livelink
from .fap.fapfile import write_fap
from .fap.mouth_cues import (
    write_moho_dat,
    write_preston_blair_dat,
    write_rhubarb_json,
    write_rhubarb_tsv,
    write_rhubarb_xml,
)
from .fap.stream import FapStream

__all__ = ["CUE_FORMATS", "MOTION_FORMATS", "WRITERS", "Writer", "format_for", "write_stream"]

Writer = Callable[[FapStream, "str | os.PathLike[str]"], None]


def _write_physical_csv(stream: FapStream, path: str | os.PathLike[str]) -> None:
    write_csv(stream, path, physical=True)


def _write_glb(stream: FapStream, path: str | os.PathLike[str]) -> None:
    from .head.gltf import write_glb  # the 3D head's modules load only when a .glb is asked for

    write_glb(stream, path)


#: format name -> (writer, file name endings); longer endings are matched first.
WRITERS: dict[str, tuple[Writer, tuple[str, ...]]] = {
    "fap": (write_fap, (".fap",)),
    "livelink": (write_livelink, (".livelink.csv",)),
    "csv-physical": (_write_physical_csv, ()),
    "csv": (write_csv, (".csv",)),
    "json": (write_json, (".json",)),
    "bvh": (write_bvh, (".bvh",)),
    "rhubarb-tsv": (write_rhubarb_tsv, (".rhubarb.tsv",)),
    "rhubarb-json": (write_rhubarb_json, (".rhubarb.json",)),
    "rhubarb-xml": (write_rhubarb_xml, (".rhubarb.xml",)),
    "moho-dat": (write_moho_dat, (".dat",)),
    "prestonblair-dat": (write_preston_blair_dat, (".prestonblair.dat",)),
    "gltf": (_write_glb, (".glb",)),
}


#: The formats of mouth cues, whose files also name the recording and end where it ends (Rhubarb's).
CUE_FORMATS = ("rhubarb-tsv", "rhubarb-json", "rhubarb-xml", "moho-dat", "prestonblair-dat")


#: The formats of motion over time that a live stream can also write (not the mouth cues, not the 3D head).
MOTION_FORMATS = ("fap", "csv", "csv-physical", "json", "bvh", "livelink")


def format_for(path: str | os.PathLike[str], format_name: str | None = None) -> str:
    """The format name for an output path (from ``format_name`` when given, else from the extension)."""
    known_formats = WRITERS
    if format_name is not None:
        if format_name not in known_formats:
            raise ConfigError(f"unknown output format {format_name!r}; choose one of {', '.join(known_formats)}")
        return format_name
    name = str(path).lower()
    endings = sorted(((ending, fmt) for fmt, (_, ends) in known_formats.items() for ending in ends),
                     key=lambda item: -len(item[0]))
    for ending, candidate in endings:
        if name.endswith(ending):
            return candidate
    known = ", ".join(ending for ending, _ in endings)
    raise ConfigError(f"cannot tell the output format of {str(path)!r} from its extension ({known}); "
                      "give output_format=NAME", parameter="output_format")


def write_stream(stream: FapStream, path: str | os.PathLike[str], format_name: str | None = None, *,
                 sound_file: str | os.PathLike[str] | None = None, duration_s: float | None = None,
                 dat_fps: float | None = None, extended_shapes: str | None = None) -> str:
    """Write ``stream`` to ``path`` in the named (or extension-implied) format, atomically.

    Parameters
    ----------
    stream : FapStream
        The frames to write.
    path : path-like
        The file; its ending chooses the format when ``format_name`` is None (``.fap``, ``.csv``, ``.json``,
        ``.bvh``, ``.livelink.csv``, ``.glb``, ``.rhubarb.tsv``, ...).
    format_name : str, optional
        A name of :data:`WRITERS`, overriding the ending.
    sound_file, duration_s : optional
        The recording the stream was made from and its length in seconds: the mouth cues' files
        (:data:`CUE_FORMATS`) name it and end where it ends, as Rhubarb's do; other formats ignore them.
    dat_fps : float, optional
        The frame rate of a ``.dat`` switch file (default 24, Rhubarb's); refused for other formats.
    extended_shapes : str, optional
        Which of Rhubarb's extended shapes G, H and X the mouth cues use (default all; Rhubarb's
        ``--extendedShapes``); refused for formats that are not cues.

    Returns
    -------
    str
        The format written.
    """
    chosen = format_for(path, format_name)
    writer = WRITERS[chosen][0]
    if dat_fps is not None and chosen not in ("moho-dat", "prestonblair-dat"):
        raise ConfigError(f"dat_fps is the frame rate of a .dat switch file; {os.fsdecode(path)!r} is {chosen}")
    if extended_shapes is not None and chosen not in CUE_FORMATS:
        raise ConfigError(f"extended_shapes chooses the shapes of mouth cues; {os.fsdecode(path)!r} is {chosen}",
                          parameter="extended_shapes")
    if chosen in CUE_FORMATS:
        extra: dict = {"sound_file": sound_file, "duration_s": duration_s}
        if dat_fps is not None:
            extra["dat_fps"] = dat_fps
        if extended_shapes is not None:
            extra["extended_shapes"] = extended_shapes
        writer(stream, Path(path), **extra)
    else:
        writer(stream, Path(path))
    return chosen
