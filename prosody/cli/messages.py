"""Where the command's own lines go: text, quiet or JSON messages, progress bars, library messages
said with the command's flags."""

from __future__ import annotations

import contextlib
import json
import os
import sys
from collections.abc import Callable
from typing import Any


class Messages:
    """Where the command's own lines go: ``text`` (lines on stderr), ``quiet`` (errors only) or ``json`` (one
    JSON object per line on stderr: ``{"event": "info"|"warning"|"error"|"progress", ...}``, for programs
    that drive the command, as Rhubarb Lip Sync's --machineReadable)."""

    mode = "text"

    def emit(self, event: str, line: str, **fields: object) -> None:
        if self.mode == "json":
            print(json.dumps({"event": event, "message": line, **fields}), file=sys.stderr, flush=True)
        elif self.mode == "text" or event == "error":
            print(line, file=sys.stderr, flush=True)


MESSAGES = Messages()


def say(line: str) -> None:
    """An informative line (a result, a server event): not shown with --quiet."""
    MESSAGES.emit("info", line)


class ProgressBar:
    """The command's one progress bar (tqdm) on a terminal, fed as a ``progress(done, total)`` callback;
    nothing in pipes or CI. Lines said while it runs are printed above it."""

    def __init__(self, description: str, unit: str) -> None:
        self.description, self.unit = description, unit
        self.bar: Any = None  # a tqdm bar once the first report arrives
        self.json = MESSAGES.mode == "json"
        self.enabled = self.json or (MESSAGES.mode == "text" and sys.stderr.isatty() and not os.environ.get("CI"))
        self._last_percent = -1

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            return
        if self.json:
            percent = int(100 * done / total) if total else 100
            if percent != self._last_percent:  # at most a hundred lines, whatever the length
                self._last_percent = percent
                unit = self.unit if total == 1 else self.unit + "s"
                MESSAGES.emit("progress", f"{self.description}: {done}/{total} {unit}", done=done, total=total)
            return
        if self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc=self.description, unit=self.unit, file=sys.stderr, leave=False)
        self.bar.update(done - self.bar.n)
        if done >= total:
            self.bar.close()

    def say(self, line: str) -> None:
        if self.bar is not None and not self.bar.disable:
            self.bar.write(line, file=sys.stderr)
        else:
            say(line)


def frame_progress(output: str, verb: str = "drawn") -> Callable[[int, int], None] | None:
    """A bar of frames analysed or drawn on a terminal; None in pipes or CI."""
    bar = ProgressBar(f"{output}: frames {verb}", "frame")
    return bar if bar.enabled else None


def forget_interrupt() -> None:
    """Keep exit code 130 after an interrupt that was handled.

    CPython remembers a KeyboardInterrupt that left a nested top-level evaluation (interrupting the import of
    some compiled modules, scipy.sparse among them, leaves that record) and then ends the process by SIGINT at
    exit, whatever code it returns. Evaluating an empty statement at top level clears the record.
    """
    if sys.implementation.name != "cpython":
        return
    with contextlib.suppress(Exception):
        import ctypes

        ctypes.pythonapi.PyRun_SimpleString(b"")


#: How the library's messages name Python arguments, and the options that set them on the command line.
_FLAGS = (
    ("AccentRule(threshold_semitones=...)", "--accent-semitones ST"),
    ("EyebrowRule(threshold_semitones=...)", "--brows thesis --eyebrow-semitones ST"),
    ("eyebrow_rule=AccentRule()", "--brows accent"),
    ("ground_truth=FILE", "--ground-truth FILE"),
    ("output_format=NAME", "--format NAME"),
    ("start_s= and duration_s=", "--start and --duration"),
    ("fps=25 or 30, or FapStream.resampled", "--fps 25 or 30"),
    ("scheduler=", "--scheduler"),
    ("(give fps=", "(give --fps "),
    ("f0_floor_hz", "--f0-floor"),
    ("f0_ceiling_hz", "--f0-ceiling"),
)


#: The same for batch, whose one option sets either rule's semitones.
_BATCH_FLAGS = (
    ("AccentRule(threshold_semitones=...)", "--brow-semitones ST"),
    ("EyebrowRule(threshold_semitones=...)", "--brows thesis --brow-semitones ST"),
)


def as_flags(message: str, command: str | None = None) -> str:
    """A library message with its Python argument names replaced by the command's options."""
    for python, flag in (_BATCH_FLAGS + _FLAGS if command == "batch" else _FLAGS):
        message = message.replace(python, flag)
    return message


def outcome_reporter(command: str, output: str, unit: str, total: int, name: Callable[[Any], str],
                      result: Callable[[Any], str | None] | None = None) -> Callable[[Any], None]:
    """The per-input callback of a folder command (batch, track): one bar over the inputs, and each input's
    warnings and failure (always) and result line (unless quiet) said above it."""
    progress = ProgressBar(output, unit)
    finished = [0]

    def on_outcome(outcome) -> None:
        for note in outcome.warnings:
            progress.say(f"prosody {command}: warning: {name(outcome)}: {as_flags(str(note), command)}")
        if outcome.status == "failed":
            progress.say(f"prosody {command}: error: {name(outcome)}: {as_flags(str(outcome.error), command)}")
        elif result is not None and (line := result(outcome)):
            progress.say(line)
        finished[0] += 1
        progress(finished[0], total)

    return on_outcome


def to_stdout(write: Callable[[str], object], name: str) -> None:
    """Run ``write(path)`` on a temporary file called ``name`` and copy it to standard output (``-o -``)."""
    import shutil
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, name)
        write(path)
        with open(path, "rb") as handle:
            shutil.copyfileobj(handle, sys.stdout.buffer)
        sys.stdout.flush()
