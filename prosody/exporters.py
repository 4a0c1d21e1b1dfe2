"""Writers of FAP streams, chosen by name or file extension in one registry (stream in, file out)."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from .errors import ConfigError
from .stream import FapStream

Writer = Callable[[FapStream, "str | os.PathLike[str]"], None]


def _write_fap(stream: FapStream, path: str | os.PathLike[str]) -> None:
    from .fapfile import write_fap

    write_fap(stream, path)


#: format name -> (writer, file extensions)
WRITERS: dict[str, tuple[Writer, tuple[str, ...]]] = {
    "fap": (_write_fap, (".fap",)),
}


def format_for(path: str | os.PathLike[str], format_name: str | None = None) -> str:
    """The format name for an output path (from ``format_name`` when given, else from the extension)."""
    if format_name is not None:
        if format_name not in WRITERS:
            raise ConfigError(f"unknown output format {format_name!r}; choose one of {', '.join(WRITERS)}")
        return format_name
    name = str(path).lower()
    for candidate, (_, extensions) in WRITERS.items():
        if any(name.endswith(extension) for extension in extensions):
            return candidate
    known = ", ".join(ext for _, exts in WRITERS.values() for ext in exts)
    raise ConfigError(f"cannot tell the output format of {str(path)!r} from its extension ({known}); "
                      "give --format")


def write_stream(stream: FapStream, path: str | os.PathLike[str], format_name: str | None = None) -> str:
    """Write ``stream`` to ``path`` in the named (or extension-implied) format; returns the format name."""
    chosen = format_for(path, format_name)
    WRITERS[chosen][0](stream, Path(path))
    return chosen
