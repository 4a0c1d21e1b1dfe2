"""Atomic file output: a file appears complete under its name, or not at all."""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """A temporary path beside ``path`` (with the same ending, for tools that go by it) that replaces ``path``
    only if the block succeeds; a failure (or an interrupt) removes it.

    The file gets the permissions a newly created file would (0666 less the umask), not the temporary
    file's private 0600.
    """
    target = Path(path)
    directory = target.parent if str(target.parent) else Path(".")
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{target.stem}.", suffix=f".part{target.suffix}", dir=directory)
    except OSError as error:
        # name the file the user asked for, not the temporary one
        raise OSError(error.errno, error.strerror, str(target)) from None
    os.close(fd)
    try:
        yield Path(tmp_name)
        os.chmod(tmp_name, 0o666 & ~_umask())
        os.replace(tmp_name, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp_name)
        raise


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike[str], *, mode: str = "w", newline: str | None = "") -> Iterator[IO]:
    """Open a temporary file beside ``path``; rename it onto ``path`` only if the block succeeds.

    A failure (or an interrupt) inside the block removes the temporary file, so no half-written output
    is ever left under the final name.
    """
    with atomic_path(path) as partial:
        handle: IO
        if "b" in mode:
            handle = open(partial, mode)
        else:
            handle = open(partial, mode, encoding="utf-8", newline=newline)
        with handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
