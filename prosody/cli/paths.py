"""Outputs that would destroy an input or each other are refused before a command runs."""

from __future__ import annotations

import argparse
import os
import sys

#: Commands whose -o may be - (standard output).
_STDOUT_COMMANDS = frozenset({"features", "convert", "stream"})


#: Options that name what a command writes.
_OUTPUT_OPTIONS = ("output", "report")


#: Parsed values that are never paths.
_NOT_PATHS = ("command", "study_command", "messages", "output", "report")


def _same_place(first: str, second: str) -> bool:
    try:
        return os.path.samefile(first, second)
    except OSError:
        return os.path.realpath(first) == os.path.realpath(second)


def _named_inputs(args: argparse.Namespace) -> list[tuple[str, str]]:
    """(option, path) of every existing file or folder any option names: whatever option names it, a path
    that exists is read, so no output may be it."""
    found = []
    for name, value in vars(args).items():
        if name in _NOT_PATHS:
            continue
        for item in value if isinstance(value, (list, tuple)) else [value]:
            if isinstance(item, (str, os.PathLike)) and os.fspath(item) not in ("", "-") \
                    and os.path.lexists(item):
                found.append((name, os.fspath(item)))
    return found


def _written_into_folder(command: str, name: str) -> bool:
    """Whether a command whose -o is a folder writes a file called ``name`` somewhere in it."""
    import fnmatch

    if command in ("compare", "batch"):
        from ..evaluation.compare import OUTPUT_NAMES

        extra = ("summary.json", "summary.md", "features.csv") if command == "batch" else ()
        return name in (*OUTPUT_NAMES, *extra) or fnmatch.fnmatch(name, "speech_driven.*.fap")
    if command == "study":
        return name == "stimuli.json" or name.endswith(".mp4")
    return False


def _flag_of(name: str) -> str:
    return "the input" if name == "input" else "-o" if name == "output" else f"--{name.replace('_', '-')}"


def check_paths(args: argparse.Namespace) -> None:
    """Refuse outputs that would destroy an input or each other, empty names, and - where it is no stream."""
    from ..errors import ConfigError

    inputs = _named_inputs(args)
    seen: list[tuple[str, str]] = []
    for name in _OUTPUT_OPTIONS:
        value = getattr(args, name, None)
        if value is None:
            continue
        flag = "-o" if name == "output" else f"--{name}"
        if not value.strip():
            raise ConfigError(f"{flag} {value!r}: give a file name")
        if value == "-":
            if name == "output" and args.command in _STDOUT_COMMANDS:
                if sys.stdout is None:
                    raise ConfigError("-o -: standard output is closed; name a file instead")
                continue
            command = " ".join(filter(None, (args.command, getattr(args, "study_command", None))))
            raise ConfigError(f"{flag} -: 'prosody {command}' writes files, not standard output; name one")
        for other_name, other in inputs + seen:
            if _same_place(value, other):
                raise ConfigError(f"{flag} {value!r} is also {_flag_of(other_name)}: writing it would destroy it; "
                                  "name another file")
        if name == "output":  # a folder of outputs: no input may be one of the files written into it
            folder = os.path.realpath(value)
            for other_name, other in inputs:
                real = os.path.realpath(other)
                if os.path.isfile(real) and real.startswith(folder + os.sep) and any(
                        _written_into_folder(args.command, os.path.basename(p)) for p in (other, real)):
                    raise ConfigError(f"{_flag_of(other_name)} {other!r} is in -o {value!r} under a name the "
                                      f"command writes there: writing it would destroy it; copy it elsewhere or "
                                      "name another folder")
        seen.append((name, value))
