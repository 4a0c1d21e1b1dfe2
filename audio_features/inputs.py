"""Opening input files: regular files only, within a size bound, never blocking.

A named pipe, a device (``/dev/zero``) or a socket given where a file is read would block for ever or read
without end; :func:`open_input` refuses them before reading a byte. The file is opened without blocking and
checked through its open descriptor, so what is checked is what is read.
"""

from __future__ import annotations

import errno
import fcntl
import os
import stat
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import IO


def _kind(mode: int) -> str:
    if stat.S_ISFIFO(mode):
        return "a named pipe"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "a device"


def open_input(path: str | os.PathLike[str], *, text: bool = False, max_bytes: int | None = None,
               encoding: str | None = None, newline: str | None = None) -> IO:
    """Open ``path`` for reading if it is a regular file of at most ``max_bytes`` bytes.

    Parameters
    ----------
    path : str or path-like
        The file; a link is followed to what it names.
    text : bool
        Open as text (with ``encoding`` and ``newline``) instead of bytes.
    max_bytes : int > 0 or None
        Largest size accepted; None: any.
    encoding, newline
        As for :func:`open`, in text mode.

    Returns
    -------
    file object
        Open for reading; the caller closes it.

    Raises
    ------
    FileNotFoundError, IsADirectoryError, PermissionError
        As :func:`open` does.
    OSError
        ``errno.EINVAL`` for a pipe, a device or a socket; ``errno.EFBIG`` for a file over ``max_bytes``.
        ``strerror`` says which, ``filename`` names the file.

    Examples
    --------
    >>> import tempfile
    >>> folder = tempfile.mkdtemp()
    >>> with open(os.path.join(folder, "a.txt"), "w") as handle:
    ...     _ = handle.write("hello")
    >>> with open_input(os.path.join(folder, "a.txt"), text=True, encoding="utf-8") as handle:
    ...     handle.read()
    'hello'
    >>> os.mkfifo(os.path.join(folder, "pipe"))
    >>> open_input(os.path.join(folder, "pipe"))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    OSError: [Errno 22] a named pipe, not a regular file: '...pipe'
    """
    # O_NONBLOCK: opening a pipe that no one writes returns at once instead of waiting for a writer
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    try:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            raise IsADirectoryError(errno.EISDIR, "is a directory, not a file", os.fspath(path))
        if not stat.S_ISREG(info.st_mode):
            raise OSError(errno.EINVAL, f"{_kind(info.st_mode)}, not a regular file", os.fspath(path))
        if max_bytes is not None and info.st_size > max_bytes:
            raise OSError(errno.EFBIG, f"larger than {_size(max_bytes)}: more than such a file can hold",
                          os.fspath(path))
        flags = fcntl.fcntl(fd, fcntl.F_GETFL)
        fcntl.fcntl(fd, fcntl.F_SETFL, flags & ~getattr(os, "O_NONBLOCK", 0))
        if text:
            return os.fdopen(fd, "r", encoding=encoding, newline=newline)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def check_input(path: str | os.PathLike[str], *, max_bytes: int | None = None) -> int:
    """Raise as :func:`open_input` does for what it would refuse; return the file's size in bytes.

    Parameters
    ----------
    path : str or path-like
        The file.
    max_bytes : int > 0 or None
        Largest size accepted; None: any.

    Returns
    -------
    int
        Its size in bytes.
    """
    with open_input(path, max_bytes=max_bytes) as handle:
        return os.fstat(handle.fileno()).st_size


def _size(n_bytes: int) -> str:
    for unit, shift in (("GiB", 30), ("MiB", 20), ("KiB", 10)):
        if n_bytes >= 1 << shift and n_bytes % (1 << shift) == 0:
            return f"{n_bytes >> shift} {unit}"
    return f"{n_bytes} bytes"


def file_sha256(path: str | os.PathLike[str]) -> str:
    """SHA-256 of a regular file's content, read in 1 MiB blocks.

    Parameters
    ----------
    path : str or path-like
        The file.

    Returns
    -------
    str
        The digest in hexadecimal.

    Raises
    ------
    OSError
        As :func:`open_input`: a missing file, a folder, a pipe or a device.
    """
    import hashlib

    digest = hashlib.sha256()
    with open_input(path) as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


@contextmanager
def reading(name: object, error: Callable[[str], Exception], *, wanted: str = "file") -> Iterator[None]:
    """Translate the OSError of reading ``name`` into ``error(message)``, one line naming the file: no such
    file, a folder where a file was wanted, or why it cannot be read (the system's words).

    Parameters
    ----------
    name : str or path-like
        The file, as messages name it.
    error : callable
        The project error to raise, called with the message.
    wanted : str
        What the file should be (``"CSV file"``): said where a folder was given.

    Yields
    ------
    None

    Examples
    --------
    >>> with reading("none.csv", ValueError):
    ...     open("/nonexistent/none.csv")
    Traceback (most recent call last):
    ValueError: none.csv: no such file
    """
    try:
        yield
    except FileNotFoundError:
        raise error(f"{name}: no such file") from None
    except IsADirectoryError:
        article = "an" if wanted[:1].lower() in "aeiou" else "a"
        raise error(f"{name}: is a directory, not {article} {wanted}") from None
    except OSError as failure:
        raise error(f"{name}: cannot be read ({failure.strerror or failure})") from None
