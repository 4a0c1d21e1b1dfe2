"""Where the command's own lines go: text, quiet or JSON messages, progress bars, library messages
said with the command's flags."""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import sys
from collections.abc import Callable, Sequence
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
            print(shown(line), file=sys.stderr, flush=True)


MESSAGES = Messages()

#: Characters a terminal would act on (C0 but tab and newline, DEL, C1): a name in a file or a path may hold them.
_CONTROL = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f]")


def shown(line: str) -> str:
    """``line`` safe for a terminal: control characters (a stream's name, a path) as their escapes, lone
    surrogates (undecodable bytes of a file name) as ``\\udcXX``.

    Examples
    --------
    >>> shown("name\\x1b[31mred\\x07")
    'name\\\\x1b[31mred\\\\x07'
    """
    line = _CONTROL.sub(lambda match: match.group().encode("unicode_escape").decode("ascii"), line)
    return line.encode("utf-8", "backslashreplace").decode("utf-8")


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


#: What the library's messages say in Python that is not one parameter, and how the command line says it.
_PHRASES = (
    ("AccentRule(threshold_semitones=...)", "--accent-semitones ST"),
    ("EyebrowRule(threshold_semitones=...)", "--brows thesis --eyebrow-semitones ST"),
    ("eyebrow_rule=AccentRule()", "--brows accent"),
    ("fps=25 or 30, or FapStream.resampled", "fps=25 or 30"),
    ("give output_format=NAME", "give --format NAME"),  # stream's option keeps the parameter's other name
)


def flag_names(parser: argparse.ArgumentParser) -> dict[str, str]:
    """A command's options by the name they are stored under (its parser's ``dest``s, which are the library's
    parameter names) -> the option that sets each (its longest spelling)."""
    return {action.dest: max(action.option_strings, key=len) for action in parser._actions if action.option_strings}


def as_flags(message: str, parser: argparse.ArgumentParser | None = None,
             parameters: Sequence[str] = ()) -> str:
    """A library message as the command line says it: the few Python phrases of :data:`_PHRASES`, then each of
    ``parameters`` (the names the error or warning carries as data, :attr:`ParameterError.parameters`) that the
    command has an option for, named by that option (``f0_floor_hz`` -> ``--f0-floor``, ``ground_truth=FILE`` ->
    ``--ground-truth FILE``). No other word of the message is taken for a parameter. Without ``parser``, the
    message is left as it is. A name without an underscore (``fps``, ``seed``) is renamed only as
    ``name=VALUE``: as a word it is also plain English."""
    if parser is None:
        return message
    for python, flag in _PHRASES:
        message = message.replace(python, flag)
    flags = flag_names(parser)
    for name in sorted((name for name in parameters if name in flags), key=len, reverse=True):
        def as_option(match: re.Match, flag: str = flags[name]) -> str:
            return f"{flag} {match.group(1)}".rstrip()

        # only where a word starts (after a space or a bracket): never inside a path or a quoted name
        message = re.sub(rf"(?<![^\s(]){re.escape(name)}=(\S*)", as_option, message)
        if "_" in name:
            message = re.sub(rf"(?<![^\s(]){re.escape(name)}\b", flags[name], message)
    return message


def said(problem: BaseException | Warning | str, parser: argparse.ArgumentParser | None = None) -> str:
    """An error's or a warning's message as the command line says it (:func:`as_flags` with the parameters it
    names)."""
    return as_flags(str(problem), parser, getattr(problem, "parameters", ()))


def outcome_reporter(parser: argparse.ArgumentParser, output: str, unit: str, total: int,
                     name: Callable[[Any], str],
                     result: Callable[[Any], str | None] | None = None) -> Callable[[Any], None]:
    """The per-input callback of a folder command (batch, track): one bar over the inputs, and each input's
    warnings and failure (always) and result line (unless quiet) said above it."""
    progress = ProgressBar(output, unit)
    finished = [0]

    def on_outcome(outcome) -> None:
        named = getattr(outcome, "parameters", ())  # what its error and warnings name, as data
        for note in outcome.warnings:
            progress.say(f"{parser.prog}: warning: {name(outcome)}: {as_flags(str(note), parser, named)}")
        if outcome.status == "failed":
            progress.say(f"{parser.prog}: error: {name(outcome)}: {as_flags(str(outcome.error), parser, named)}")
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
