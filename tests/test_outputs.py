"""Where outputs go: devices and pipes written through, folders refused, leftovers of killed runs removed,
long names, disk errors named after the user's file."""

from __future__ import annotations

import errno
import os
import stat
import subprocess
import sys
import threading

import numpy as np
import pytest

from audio_features.atomic import atomic_write, interrupts_held
from prosody.cli import main

SR = 16000


@pytest.mark.skipif(os.geteuid() != 0, reason="creating a device node needs root")
def test_a_device_node_is_written_through_never_replaced(tmp_path, speech) -> None:
    null = tmp_path / "null"
    os.mknod(null, 0o666 | stat.S_IFCHR, os.makedev(1, 3))  # our own null device, in a temporary folder
    assert main(["convert", str(speech), "-o", str(null), "--format", "fap"]) == 0
    assert stat.S_ISCHR(os.stat(null).st_mode)
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_a_fifo_is_written_through(tmp_path, speech) -> None:
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    received: list[bytes] = []
    reader = threading.Thread(target=lambda: received.append(fifo.read_bytes()))
    reader.start()
    assert main(["convert", str(speech), "-o", str(fifo)]) == 0
    reader.join(timeout=30)
    assert received and received[0].startswith(b"frame,time_s,fap3_open_jaw")
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)


def test_a_directory_is_refused_with_its_name(tmp_path, speech, capsys) -> None:
    folder = tmp_path / "out.fap"
    folder.mkdir()
    assert main(["convert", str(speech), "-o", str(folder)]) == 1
    err = capsys.readouterr().err
    assert str(folder) in err and "is a directory" in err and err.count("\n") == 1
    assert folder.is_dir() and list(folder.iterdir()) == []


def test_an_empty_output_name_is_refused(speech, capsys) -> None:
    assert main(["convert", str(speech), "-o", "", "--format", "fap"]) == 2
    assert "give a file name" in capsys.readouterr().err


def test_leftovers_of_a_killed_writer_are_removed_by_the_next_write(tmp_path) -> None:
    # a process that is gone: start one and wait for it, so its pid is not running
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    pid = int(gone.stdout)
    stale = tmp_path / f".out.{pid}.abc123.part.fap"
    stale.write_text("half written")
    alive = tmp_path / f".out.{os.getppid()}.def456.part.fap"  # a writer that is still running: kept
    alive.write_text("being written")
    with atomic_write(tmp_path / "out.fap") as handle:
        handle.write("done\n")
    assert (tmp_path / "out.fap").read_text() == "done\n"
    assert not stale.exists() and alive.exists()


def test_long_legal_names_work(tmp_path) -> None:
    name = "x" * 250 + ".fap"  # 254 bytes: legal; the temporary name must not be longer
    with atomic_write(tmp_path / name) as handle:
        handle.write("ok\n")
    assert (tmp_path / name).read_text() == "ok\n"


def test_a_full_disk_names_the_users_file(tmp_path, monkeypatch) -> None:
    target = tmp_path / "out.csv"

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    with pytest.raises(OSError) as info, atomic_write(target) as handle:
        monkeypatch.setattr(handle, "write", full)
        handle.write("x")
    assert info.value.filename == str(target) and info.value.errno == errno.ENOSPC
    assert list(tmp_path.iterdir()) == []


def test_a_regular_file_is_still_replaced_atomically(tmp_path, speech) -> None:
    out = tmp_path / "a.csv"
    out.write_text("old")
    assert main(["convert", str(speech), "-o", str(out)]) == 0
    assert np.loadtxt(out, delimiter=",", skiprows=1).shape[0] == 51


def _delivered() -> None:
    """Give a signal sent to this process the moment it needs to arrive: the kernel may hand it to another thread
    (a library's worker), whose handler then tells the main thread, so it is not always there when ``kill``
    returns (on a busy machine, seen as late as the end of the block)."""
    import time

    deadline = time.monotonic() + 0.2
    while time.monotonic() < deadline:
        time.sleep(0.01)


def test_an_interrupt_while_the_temporary_file_is_made_leaves_nothing(tmp_path, monkeypatch) -> None:
    import signal
    import tempfile

    from audio_features.atomic import atomic_path

    made = tempfile.mkstemp

    def interrupted_mkstemp(*args, **kwargs):
        result = made(*args, **kwargs)
        os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C right after the file exists, before its name is returned
        _delivered()
        return result

    monkeypatch.setattr(tempfile, "mkstemp", interrupted_mkstemp)
    with pytest.raises(KeyboardInterrupt):
        with atomic_path(tmp_path / "out.fap"):
            pytest.fail("the block must not start after an interrupt")
    assert list(tmp_path.iterdir()) == []


def test_interrupts_held_act_when_the_block_ends() -> None:
    import signal

    reached = []
    with pytest.raises(KeyboardInterrupt):
        with interrupts_held():
            os.kill(os.getpid(), signal.SIGINT)
            _delivered()
            reached.append("the rest of the block")
    assert reached == ["the rest of the block"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # put back
