"""Atomic file output: a file appears complete under its name, or not at all.

Regular files are written to a temporary file beside the target and renamed over it. A target that exists
and is not a regular file is never replaced: a device or a FIFO (``/dev/null``, a named pipe a player reads
from) is written through directly, and a directory is refused.

Temporary names are ``.<stem>.<pid>.<random>.part<ending>``, short enough for any legal target name. One
left behind by a process that was killed (SIGKILL, power loss) is removed the next time that target is
written, once its process is gone.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import signal
import stat
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import IO

#: Bytes of the target's stem kept in a temporary name (file names are limited to 255 bytes).
_STEM_BYTES = 80
#: Longest ending kept in a temporary name.
_SUFFIX_CHARACTERS = 16


def _read_umask() -> int:
    """The process's umask. Linux says it in /proc, so it is never flipped, even for an instant, while another
    thread (the live server's) creates a file; elsewhere it is set and set back."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _short_stem(stem: str) -> str:
    encoded = stem.encode("utf-8", "surrogateescape")[:_STEM_BYTES]
    return encoded.decode("utf-8", "ignore") or "output"


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # someone else's process
    return True


def _remove_stale(directory: Path, prefix: str) -> None:
    """Remove temporary files of ``prefix`` left by processes that no longer run."""
    pattern = re.compile(re.escape(prefix) + r"(\d+)\.[^.]+\.part")
    with contextlib.suppress(OSError):
        for entry in os.scandir(directory):
            match = pattern.match(entry.name)
            if match and int(match.group(1)) != os.getpid() and not _alive(int(match.group(1))):
                with contextlib.suppress(OSError):
                    os.unlink(entry.path)


def _not_regular(target: Path) -> str | None:
    """'directory' or 'special' if ``target`` exists and is not a regular file, else None."""
    try:
        mode = os.stat(target).st_mode
    except (FileNotFoundError, NotADirectoryError):
        return None
    if stat.S_ISDIR(mode):
        return "directory"
    return None if stat.S_ISREG(mode) else "special"


@contextlib.contextmanager
def interrupts_held() -> Iterator[None]:
    """Ctrl-C and SIGTERM that arrive inside the block act when it ends (only the main thread sets handlers;
    elsewhere the block runs as it is).

    Yields
    ------
    None
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []
    previous = {sig: signal.signal(sig, lambda signum, frame: held.append(signum))
                for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        for signum in held[:1]:
            handler = previous[signal.Signals(signum)]
            if callable(handler):
                handler(signum, None)
            elif handler == signal.SIG_DFL:
                signal.raise_signal(signum)  # what it would have done (SIG_IGN: nothing)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """A temporary path beside ``path`` (with the same ending, for tools that go by it) that replaces ``path``
    only if the block succeeds; a failure (or an interrupt) removes it.

    The file keeps the permissions of the file it replaces; a new one gets those a newly created file would
    (0666 less the umask), not the temporary file's private 0600. A device or FIFO at ``path`` is yielded
    itself (written through, never replaced); a directory raises :class:`IsADirectoryError`.

    Parameters
    ----------
    path : str or path-like
        The file to replace.

    Yields
    ------
    pathlib.Path
        The temporary path to write.
    """
    if not os.fspath(path):
        raise FileNotFoundError(errno.ENOENT, "no output file name given", "''")
    target = Path(path)
    kind = _not_regular(target)
    if kind == "directory":
        raise IsADirectoryError(errno.EISDIR, "is a directory, not a file to write", str(target))
    if kind == "special":
        yield target
        return
    directory = target.parent if str(target.parent) else Path(".")
    suffix = target.suffix if len(target.suffix) <= _SUFFIX_CHARACTERS else ""
    prefix = f".{_short_stem(target.stem)}."
    _remove_stale(directory, prefix)
    tmp_name = ""
    try:
        # an interrupt between the file's creation and the block below would leave it behind
        with interrupts_held():
            fd, tmp_name = tempfile.mkstemp(prefix=f"{prefix}{os.getpid()}.", suffix=f".part{suffix}",
                                            dir=directory)
            os.close(fd)
    except OSError as error:
        # name the file the user asked for, not the temporary one
        raise OSError(error.errno, error.strerror, str(target)) from None
    except BaseException:  # the interrupt held while the file was made
        if tmp_name:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp_name)
        raise
    try:
        try:
            permissions = stat.S_IMODE(os.stat(target).st_mode)
        except OSError:
            permissions = 0o666 & ~_read_umask()
        yield Path(tmp_name)
        os.chmod(tmp_name, permissions)
        os.replace(tmp_name, target)
    except OSError as error:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp_name)
        if error.filename in (tmp_name, str(tmp_name)):
            # a full disk or a lost folder while writing: say so about the user's file
            raise OSError(error.errno, error.strerror, str(target)) from None
        raise
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp_name)
        raise


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike[str], *, mode: str = "w", newline: str | None = "") -> Iterator[IO]:
    """Open a temporary file beside ``path``; rename it onto ``path`` only if the block succeeds.

    A failure (or an interrupt) inside the block removes the temporary file, so no half-written output
    is ever left under the final name. A device or FIFO is written through (see :func:`atomic_path`).

    Parameters
    ----------
    path : str or path-like
        The file to replace.
    mode : str
        ``"w"`` (text) or ``"wb"`` (bytes).
    newline : str or None
        As for :func:`open`.

    Yields
    ------
    file object
        The temporary file, open for writing.
    """
    with atomic_path(path) as partial:
        handle: IO
        if "b" in mode:
            handle = open(partial, mode)
        else:
            # file names that are not UTF-8 (bytes kept as surrogates) are written back as the same bytes
            handle = open(partial, mode, encoding="utf-8", errors="surrogateescape", newline=newline)
        try:
            with handle:
                yield handle
                handle.flush()
                with contextlib.suppress(OSError):  # devices and pipes cannot be synced
                    if stat.S_ISREG(os.fstat(handle.fileno()).st_mode):
                        os.fsync(handle.fileno())
        except OSError as error:
            if error.filename is None:
                # errors of write() carry no file name (ENOSPC): name the user's file
                raise OSError(error.errno, error.strerror, str(path)) from None
            raise
