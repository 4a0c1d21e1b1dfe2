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

from audio_features.atomic import atomic_write
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
    assert received and received[0].startswith(b"frame,time_s,fap1_viseme_na,fap3_open_jaw")  # the viseme said first
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


def _in_a_fresh_process(body: str) -> None:
    """Run ``body`` (a test's code, asserting what it must) in a new interpreter: the signal state a test of
    Ctrl-C depends on (handlers, masks, threads that may take a signal) is the whole process's, and earlier tests
    in this one (native libraries, thread pools) may have changed it."""
    import subprocess
    import sys
    import textwrap

    # as a terminal's Ctrl-C finds a program: SIGINT raising KeyboardInterrupt, not blocked (a child inherits
    # its parent's mask and an ignored SIGINT)
    prologue = ("import signal\n"
                "signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})\n"
                "signal.signal(signal.SIGINT, signal.default_int_handler)\n")
    done = subprocess.run([sys.executable, "-c", prologue + textwrap.dedent(body)], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    assert done.stdout.strip().endswith("ok"), done.stdout + done.stderr


def test_an_interrupt_while_the_temporary_file_is_made_leaves_nothing(tmp_path) -> None:
    _in_a_fresh_process(f"""
        import os, signal, tempfile
        from pathlib import Path
        from audio_features.atomic import atomic_path

        made = tempfile.mkstemp

        def interrupted_mkstemp(*args, **kwargs):
            result = made(*args, **kwargs)
            os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C right after the file exists, before its name is returned
            return result

        tempfile.mkstemp = interrupted_mkstemp
        try:
            with atomic_path(Path({str(tmp_path)!r}) / "out.fap"):
                raise SystemExit("the block must not start after an interrupt")
        except KeyboardInterrupt:
            pass
        else:
            raise SystemExit("no KeyboardInterrupt")
        assert list(Path({str(tmp_path)!r}).iterdir()) == [], "a file was left"
        print("ok")
    """)


def test_interrupts_held_act_when_the_block_ends() -> None:
    _in_a_fresh_process("""
        import os, signal
        from audio_features.atomic import interrupts_held

        reached = []
        try:
            with interrupts_held():
                os.kill(os.getpid(), signal.SIGINT)
                reached.append("the rest of the block")
        except KeyboardInterrupt:
            pass
        else:
            raise SystemExit("no KeyboardInterrupt at the end of the block")
        assert reached == ["the rest of the block"], reached
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # put back
        print("ok")
    """)


@pytest.mark.slow
def test_ctrl_c_at_any_moment_of_the_start_says_interrupted(tmp_path) -> None:
    """Ctrl-C 0.1-0.5 s after the start (the interpreter's start, the imports, Praat's library loading) printed a
    traceback in 12 of 40 runs (``ImportError: KeyboardInterrupt`` among them); now every run ends with
    "interrupted" and 130, or, when the work was already done, 0."""
    import signal
    import subprocess
    import sys
    import time

    from conftest import REPO

    for k in range(16):
        process = subprocess.Popen([sys.executable, "-m", "prosody", "convert",
                                    str(REPO / "samples" / "arctic_a0009.wav"), "-o", str(tmp_path / "x.fap")],
                                   stderr=subprocess.PIPE, text=True, cwd=tmp_path,
                                   preexec_fn=lambda: signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT}))
        time.sleep(0.05 + 0.45 * k / 15)
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=60)
        assert "Traceback" not in err and process.returncode in (0, 130), (k, process.returncode, err)
        if process.returncode == 130:
            assert err.strip().endswith("interrupted"), err


def test_ctrl_c_that_a_compiled_module_reports_as_an_import_error_says_interrupted() -> None:
    """NumPy stopped by Ctrl-C while it loads raises an ImportError of its own ("PyCapsule_Import could not import
    module datetime") that does not name the interrupt: the command still ends with "interrupted" and 130. Here
    the command's import sends the interrupt to its own process and turns it into such an error."""
    import subprocess
    import sys

    from conftest import REPO

    program = """
import os, signal, sys, time
class Stopped:
    def find_spec(self, name, path=None, target=None):
        if name == "prosody.cli.app":
            try:
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(5)
            except KeyboardInterrupt:
                pass
            raise ImportError('PyCapsule_Import could not import module "datetime"')
sys.meta_path.insert(0, Stopped())
from prosody.__main__ import main
sys.exit(main())
"""
    done = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True, cwd=REPO, timeout=60)
    assert (done.returncode, done.stderr.strip()) == (130, "prosody: interrupted"), done.stderr
