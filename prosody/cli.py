"""The ``prosody`` command: a thin shell over the package's functions.

This is the only module that reads argv and decides exit codes: 0 ok, 1 processing error, 2 bad usage.
Heavy libraries are imported inside each command, so a command pays only for what it uses.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import os
import sys
from collections.abc import Callable, Sequence
from typing import Any

from audio_features.defaults import DEFAULT_F0_CEILING_HZ, DEFAULT_F0_FLOOR_HZ, DEFAULT_FPS

EXIT_OK, EXIT_FAILURE, EXIT_USAGE = 0, 1, 2


class _Parser(argparse.ArgumentParser):
    """argparse with the package's one-line error style (exit code 2)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value > 0 or value != value or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def _whole_number(low: int, high: int, shown: str) -> Callable[[str], int]:
    """An argparse type: a whole number in [low, high] (``shown`` is how the range is said)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"expected a whole number from {shown}, got {text!r}")
        return value

    return parse


def _lookahead(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of milliseconds, got {text!r}") from None
    if not 0 <= value <= 2000:
        raise argparse.ArgumentTypeError(f"expected milliseconds from 0 to 2000, got {text!r}")
    return value


_seed = _whole_number(0, 2**63 - 1, "0 to 2**63-1")


def _number_in(low: float, high: float, *, low_open: bool = False) -> Callable[[str], float]:
    """An argparse type: a finite number in [low, high] (or (low, high] with ``low_open``)."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        if not (low < value <= high if low_open else low <= value <= high):
            bracket = "(" if low_open else "["
            raise argparse.ArgumentTypeError(f"expected a number in {bracket}{low:g}, {high:g}], got {text!r}")
        return value

    return parse


#: Largest drawing exaggeration (100: a 1-degree nod drawn as 100 degrees).
_exaggeration = _number_in(0, 100, low_open=True)
#: Times within a recording, in s (a million seconds: eleven days).
_seconds = _number_in(0, 1e6)
_seeds = _whole_number(1, 1000, "1 to 1000")
_sample_rate = _whole_number(8000, 768000, "8000 to 768000 (Hz)")


def _add_seeds_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seeds", type=_seeds, default=10, metavar="N",
                        help="average the measures of the random and speech-driven conditions (and of the "
                             "control) over N seeds from --seed on (default 10); the written streams use --seed")


def _add_analysis_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--fps", type=_number_in(1, 1000), default=DEFAULT_FPS,
                        help="frames per second of the output grid (default 30, 1 to 1000; frame k is at k/fps s)")
    parser.add_argument("--f0-floor", type=_positive_float, default=DEFAULT_F0_FLOOR_HZ, metavar="HZ",
                        help=f"lowest F0 the pitch tracker looks for, in Hz (default {DEFAULT_F0_FLOOR_HZ:g})")
    parser.add_argument("--f0-ceiling", type=_positive_float, default=DEFAULT_F0_CEILING_HZ, metavar="HZ",
                        help=f"highest F0 the pitch tracker looks for, in Hz (default {DEFAULT_F0_CEILING_HZ:g})")


def _add_generator_options(parser: argparse.ArgumentParser, *, live: bool = False) -> None:
    if live:
        parser.add_argument("--model", default=None, metavar="FILE",
                            help="live head model: a file from 'prosody train --kind live' (default: the shipped "
                                 "model that reads the most within --lookahead-ms)")
    else:
        parser.add_argument("--model", default=None, metavar="NAME|FILE",
                            help="head model for the speech-driven condition: 'prosodic' (the default: motion of "
                                 "a person's size timed by the speech), 'arx' (the thesis's linear model), 'pad' "
                                 "(seed 000's nod per prosodic word), 'pad-random' (its random baseline), or a "
                                 "file from 'prosody train'")
    parser.add_argument("--seed", type=_seed, default=0,
                        help="seed of the random condition and of the speech-driven head's motion (a whole "
                             "number >= 0, default 0: the same seed gives the same stream)")


def _add_motion_options(parser: argparse.ArgumentParser, *, live: bool = False) -> None:
    """Condition, generator and intensity options of the commands that make one stream (convert, preview,
    and without recorded motion, stream)."""
    parser.add_argument("--condition", default="speech",
                        choices=["speech", "random", "none"] if live else ["speech", "random", "none", "truth"],
                        help="which animation to produce (default speech)")
    if not live:
        parser.add_argument("--ground-truth", default=None, metavar="FILE",
                            help="recorded motion for --condition truth: <clip>.head.csv or .fap")
    _add_generator_options(parser, live=live)
    controls = parser.add_argument_group("intensity (1 keeps the motion as computed, 0.5 halves it)")
    for channel, what in (("pitch", "head nods (FAP 48)"), ("yaw", "head turns (FAP 49)"),
                          ("roll", "head tilts (FAP 50)"), ("brow", "eyebrow raises (FAP 31-34)")):
        controls.add_argument(f"--{channel}-gain", type=_number_in(0, 100), default=1.0, metavar="G",
                              help=f"scale the {what} by G (default 1; 0 to 100, the head and brows kept within "
                                   "what a person can do)")
    controls.add_argument("--lip-gain", type=_number_in(0, 100), default=1.0, metavar="G",
                          help="scale the lips' motion (FAP 3-11, 16-17, 51-58) by G (default 1)")
    controls.add_argument("--off", action="append", default=[], metavar="CHANNEL[,CHANNEL]",
                          help="leave channels out of the output: pitch, yaw, roll, brows, lips (repeatable)")
    _add_expressivity_options(parser)
    if live:
        from .motion.expressions import EXPRESSIONS

        parser.add_argument("--lips", dest="live_lips", default="acoustic", choices=["acoustic", "none"],
                            help="lips from the live acoustic mouth model (default; the same in every condition), "
                                 "or none; the visemes of convert need whole phones and their neighbours, so they "
                                 "and --transcript (aligned to the whole recording) are not offered live")
        parser.add_argument("--expression", default=None, metavar="NAME[:INTENSITY]|FILE.csv",
                            help=f"a facial expression over the stream ({', '.join(EXPRESSIONS)}; intensity 0-1, "
                                 "default 1), or a CSV file of timed ones (start_s,end_s,expression,intensity, "
                                 "times from the stream's start), mixed with the lips as in convert")
    else:
        _add_face_options(parser)


def _add_expressivity_options(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group(
        "expressivity", "Greta's six expressivity parameters, on every head and brow generator alike (the "
        "speech-driven head of any --model, the brows of either rule, the random condition, and live). The "
        "defaults leave the motion as generated.")
    group.add_argument("--activation", type=_number_in(0, 1), default=1.0, metavar="OAC",
                       help="how often gestures happen, 0..1 (default 1): below 1 the head holds still during "
                            "its weakest moments (about 1 - OAC of the time) and only that share of the brow "
                            "raises is kept")
    group.add_argument("--spatial", type=_number_in(-1, 1), default=0.0, metavar="SPC",
                       help="amplitude about rest, -1..1 (default 0): the motion times 2^SPC")
    group.add_argument("--temporal", type=_number_in(-1, 1), default=0.0, metavar="TMP",
                       help="duration of movements, -1..1 (default 0): above 0 longer and slower, below 0 "
                            "shorter and quicker; brow raises held longer or cut shorter")
    group.add_argument("--fluidity", type=_number_in(-1, 1), default=0.0, metavar="FLD",
                       help="smoothness, -1..1 (default 0): above 0 the quick jerks are smoothed away, below 0 "
                            "they are boosted")
    group.add_argument("--power", type=_number_in(-1, 1), default=0.0, metavar="PWR",
                       help="sharpness of accents, -1..1 (default 0): above 0 strong moments grow and weak ones "
                            "shrink (bursts and holds) and brow raises flick up, below 0 the motion evens out")
    group.add_argument("--repetition", type=_number_in(0, 1), default=0.0, metavar="REP",
                       help="repeated nods (and a second brow raise) on strong accents, 0..1 (default 0)")
    group.add_argument("--still", action="store_true",
                       help="a head that keeps still but for an idle sway, and brows at rest (--activation 0)")


def _expressivity(args: argparse.Namespace):
    """The Expressivity of the command line's controls, or None where they keep the motion as generated."""
    from .errors import ConfigError
    from .motion.expressivity import Expressivity

    controls = Expressivity(activation=args.activation, spatial=args.spatial, temporal=args.temporal,
                            fluidity=args.fluidity, power=args.power, repetition=args.repetition)
    if args.still:
        if args.activation != 1.0:
            raise ConfigError("--still is --activation 0: give one of them")
        controls = controls.with_changes(activation=0.0)
    return None if controls.is_neutral else controls


def _add_face_options(parser: argparse.ArgumentParser) -> None:
    from .motion.expressions import EXPRESSIONS

    face = parser.add_argument_group(
        "lips and expressions", "The lips move with the speech in every condition alike: phones recognised by "
        "PocketSphinx become MPEG-4 visemes blended over time by dominance functions (--lips visemes, the "
        "default), or an acoustic model maps the spectrum to the mouth's shape (--lips acoustic, any "
        "language). An expression is neutral unless asked.")
    face.add_argument("--lips", default="visemes", choices=["visemes", "acoustic", "none"],
                      help="how the lips move (default visemes; none: no lip FAPs)")
    face.add_argument("--transcript", default=None, metavar="TEXT|FILE",
                      help="what is said (the text, or a text file): its words are aligned to the audio for the "
                           "visemes; words the pronouncing dictionary lacks are left out, and a text that does "
                           "not fit the audio is ignored with a warning")
    face.add_argument("--language", default=None, metavar="CODE",
                      help="the transcript's language, an eSpeak NG code (es, de, fr, cmn, ...; 'prosody "
                           "languages' lists them): its phones come from eSpeak NG and are aligned to the "
                           "recording, in any language (default: English, aligned by PocketSphinx)")
    face.add_argument("--mouth-model", default=None, metavar="FILE",
                      help="with --lips acoustic: a mouth model from 'prosody train --kind mouth' (default: the "
                           "shipped one)")
    face.add_argument("--expression", default=None, metavar="NAME[:INTENSITY]|FILE.csv",
                      help=f"a facial expression for the whole recording ({', '.join(EXPRESSIONS)}; intensity "
                           "0-1, default 1), or a CSV file of timed ones with the columns "
                           "start_s,end_s,expression,intensity; blended in and out over about half a second and "
                           "mixed with the lips so they still articulate")
    face.add_argument("--pad", default=None, metavar="P,A,D|FILE.csv",
                      help="an emotional state: pleasure, arousal and dominance, each -1..1, for the whole "
                           "recording (e.g. 0.5,0.6,0), or a CSV file of timed ones with the columns "
                           "start_s,end_s,pleasure,arousal,dominance. It shows on the face (brows raised or "
                           "squeezed, eyes opened: seed 000's partial expressions) and drives --model pad's "
                           "gestures (P, and A shifting each word's arousal); write --pad=-0.5,0.3,0 when it "
                           "starts with a minus")
    face.add_argument("--pad-map", default=None, metavar="FILE.json",
                      help="with --pad: a JSON file replacing the map from PAD to the partial expressions "
                           "(see the README)")


def _analysis_kwargs(args: argparse.Namespace) -> dict:
    return {"fps": args.fps, "f0_floor_hz": args.f0_floor, "f0_ceiling_hz": args.f0_ceiling}


def _finite_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if value != value or value in (float("inf"), float("-inf")):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


#: Options of the thesis's eyebrow rule and the EyebrowRule fields they set.
_THESIS_BROW_OPTIONS = {"eyebrow_threshold": "threshold_hz", "eyebrow_semitones": "threshold_semitones",
                        "energy_threshold": "energy_threshold_db", "energy_relative": "energy_relative_db"}


def _add_eyebrow_options(parser: argparse.ArgumentParser) -> None:
    from .motion.eyebrows import AccentRule, EyebrowRule

    accent, thesis = AccentRule(), EyebrowRule()  # the defaults the help states are the rules' own
    group = parser.add_argument_group(
        "eyebrows", "The speech-driven brows rise on pitch accents judged against the speaker's own voice "
                    "(accent rule, the default), or follow the thesis's rule (--brows thesis): raise when the "
                    "pitch crosses 207 Hz, hold 300 ms and then while the energy stays at or above 45 dB.")
    group.add_argument("--brows", default="accent", choices=["accent", "thesis"],
                       help="eyebrow rule (default accent: raise where the voice, at speaking loudness, goes "
                            "--accent-semitones above the speaker's median pitch; for 0.3 to 1.2 s)")
    group.add_argument("--accent-semitones", type=_finite_float, default=None, metavar="ST",
                       help="accent rule: semitones above the speaker's median pitch that raise the brows "
                            f"(default {accent.threshold_semitones:g}; lower raises more often)")
    group.add_argument("--eyebrow-threshold", type=_positive_float, default=None, metavar="HZ",
                       help="thesis rule: a rising crossing of the conditioned pitch through HZ raises the brows "
                            f"(default {thesis.threshold_hz:g})")
    group.add_argument("--eyebrow-semitones", type=_finite_float, default=None, metavar="ST",
                       help="thesis rule, speaker-relative threshold instead of --eyebrow-threshold: ST semitones "
                            "above the recording's median pitch (e.g. 4)")
    group.add_argument("--energy-threshold", type=_finite_float, default=None, metavar="DB",
                       help=f"thesis rule: after {thesis.min_hold_s * 1000:g} ms the raise lasts while energy >= DB, "
                            f"in dB re 2e-5 Pa (default {thesis.energy_threshold_db:g})")
    group.add_argument("--energy-relative", type=_finite_float, default=None, metavar="DB",
                       help="thesis rule, calibrated for recording level instead of --energy-threshold: the "
                            "recording's median voiced energy + DB (e.g. -25)")


def _eyebrow_rule(args: argparse.Namespace):
    from .errors import ConfigError
    from .motion.eyebrows import AccentRule, EyebrowRule

    given = {name: getattr(args, name) for name in _THESIS_BROW_OPTIONS if getattr(args, name) is not None}
    flags = ", ".join(f"--{name.replace('_', '-')}" for name in given)
    if args.brows == "accent":
        if given:
            raise ConfigError(f"{flags} set(s) the thesis's eyebrow rule: add --brows thesis")
        if args.accent_semitones is None:
            return AccentRule()
        return AccentRule(threshold_semitones=args.accent_semitones)
    if args.accent_semitones is not None:
        raise ConfigError("--accent-semitones sets the accent rule: it does not apply with --brows thesis")
    for pair in (("eyebrow_semitones", "eyebrow_threshold"), ("energy_relative", "energy_threshold")):
        if all(name in given for name in pair):
            raise ConfigError(f"--{pair[0].replace('_', '-')} replaces --{pair[1].replace('_', '-')}: give one")
    return EyebrowRule(**{_THESIS_BROW_OPTIONS[name]: value for name, value in given.items()})


# commands -----------------------------------------------------------------------------------------------
def _cmd_languages(args: argparse.Namespace) -> int:
    from audio_features.espeak import languages

    for code, voice in languages().items():
        print(f"{code}\t{voice}")
    return EXIT_OK


def _cmd_features(args: argparse.Namespace) -> int:
    from audio_features import extract_features

    from .errors import ConfigError

    if args.output != "-" and not args.output.lower().endswith(".csv"):
        raise ConfigError(f"-o {args.output!r}: features are written as CSV; name the file .csv (or - for "
                          "standard output)")
    if args.output == "-":
        features = extract_features(args.input, **_analysis_kwargs(args))
        _to_stdout(features.write_csv, "features.csv")
        return EXIT_OK

    features = extract_features(args.input, **_analysis_kwargs(args))
    features.write_csv(args.output)
    _say(f"{args.output}: {features.n_frames} frames at {features.fps:g} fps "
          f"({features.duration_s:.2f} s, {int(features.f0.voiced.sum())} voiced)")
    return EXIT_OK


def _motion_kwargs(args: argparse.Namespace) -> dict:
    """The keyword arguments of :func:`prosody.jobs.pipeline.convert` set by :func:`_add_motion_options`."""
    gains = {"pitch": args.pitch_gain, "yaw": args.yaw_gain, "roll": args.roll_gain, "brows": args.brow_gain,
             "lips": args.lip_gain}
    disabled = [name.strip() for value in args.off for name in value.split(",") if name.strip()]
    face: dict = {}
    if hasattr(args, "live_lips"):
        face = {"live_lips": args.live_lips != "none", "expression": args.expression}
    if hasattr(args, "lips"):
        face = {"lips": None if args.lips == "none" else args.lips, "transcript": args.transcript,
                "expression": args.expression, "mouth_model": args.mouth_model, "pad": args.pad,
                "pad_map": args.pad_map, "language": args.language}
    return {"condition": args.condition, "ground_truth": getattr(args, "ground_truth", None), "model": args.model,
            "seed": args.seed, "eyebrow_rule": _eyebrow_rule(args), "gains": gains, "disabled": disabled, **face,
            "expressivity": _expressivity(args),
            **_analysis_kwargs(args)}


def _to_stdout(write: Callable[[str], object], name: str) -> None:
    """Run ``write(path)`` on a temporary file called ``name`` and copy it to standard output (``-o -``)."""
    import shutil
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, name)
        write(path)
        with open(path, "rb") as handle:
            shutil.copyfileobj(handle, sys.stdout.buffer)
        sys.stdout.flush()


def _check_motion_options(args: argparse.Namespace) -> None:
    """Options that would make the output silently other than asked are refused."""
    from .errors import ConfigError

    if getattr(args, "ground_truth", None) is not None and args.condition != "truth":
        raise ConfigError(f"--ground-truth is the recorded motion of --condition truth; it is not used by "
                          f"--condition {args.condition}")
    if getattr(args, "model", None) is not None and args.condition in ("none", "random", "truth"):
        raise ConfigError(f"--model is the head model of --condition speech; it is not used by --condition "
                          f"{args.condition}")
    off = {name.strip() for value in args.off for name in value.split(",") if name.strip()}
    lips = getattr(args, "lips", getattr(args, "live_lips", "none"))
    channels = {"pitch", "yaw", "roll", "brows"} | ({"lips"} if lips != "none" else set())
    if channels <= off and getattr(args, "expression", None) is None:
        raise ConfigError(f"--off leaves out every channel ({', '.join(sorted(channels))}): the output would be "
                          "empty")
    if getattr(args, "mouth_model", None) is not None and getattr(args, "lips", None) != "acoustic":
        raise ConfigError("--mouth-model is the model of --lips acoustic; add --lips acoustic")
    if getattr(args, "transcript", None) is not None and getattr(args, "lips", None) != "visemes":
        raise ConfigError("--transcript is read by the visemes; it is not used by --lips "
                          f"{getattr(args, 'lips', 'none')}")
    if getattr(args, "language", None) is not None and getattr(args, "transcript", None) is None:
        raise ConfigError("--language is the transcript's language: give --transcript too (without one, "
                          "--lips acoustic follows any language)")
    if getattr(args, "pad_map", None) is not None and args.pad is None:
        raise ConfigError("--pad-map maps the state of --pad to the face; give --pad too")
    if args.condition in ("none", "truth") and _expressivity(args) is not None:
        raise ConfigError(f"the expressivity controls shape generated motion; --condition {args.condition} has none "
                          "(choose speech or random)")


def _cmd_convert(args: argparse.Namespace) -> int:
    from .errors import ConfigError
    from .jobs.pipeline import convert

    _check_motion_options(args)
    if args.format is None and args.output.lower().endswith((".mp4", ".gif", ".webm", ".mov", ".mkv", ".avi")):
        raise ConfigError(f"-o {args.output!r}: convert writes motion (.fap, .csv, .json, .bvh, .livelink.csv); "
                          f"to draw a video, use 'prosody preview {args.input} -o {args.output}'")
    if args.output == "-":
        if args.format is None:
            raise ConfigError("-o - writes to standard output: give --format (fap, csv, csv-physical, json, bvh, "
                              "livelink)")
        holder: list = []

        def write(path: str) -> None:
            holder.append(convert(args.input, path, base=args.base, output_format=args.format,
                                  **_motion_kwargs(args)))

        from pathlib import Path

        _to_stdout(write, Path(args.input).stem + "." + args.format)  # the stream keeps the input's name
        stream = holder[0]
    else:
        stream = convert(args.input, args.output, base=args.base, output_format=args.format,
                         progress=_frame_progress(args.input, "analysed"), **_motion_kwargs(args))
    faps = " ".join(map(str, stream.active_faps))
    written = args.format or ""
    if written == "bvh" or (not written and args.output.lower().endswith(".bvh")):
        faps = "48 49 50 (BVH holds the head only)"
    _say(f"{args.output}: {stream.n_frames} frames at {stream.fps:g} fps, FAPs {faps}")
    return EXIT_OK


class _Messages:
    """Where the command's own lines go: ``text`` (lines on stderr), ``quiet`` (errors only) or ``json`` (one
    JSON object per line on stderr: ``{"event": "info"|"warning"|"error"|"progress", ...}``, for programs
    that drive the command, as Rhubarb Lip Sync's --machineReadable)."""

    mode = "text"

    def emit(self, event: str, line: str, **fields: object) -> None:
        if self.mode == "json":
            print(json.dumps({"event": event, "message": line, **fields}), file=sys.stderr, flush=True)
        elif self.mode == "text" or event == "error":
            print(line, file=sys.stderr, flush=True)


_MESSAGES = _Messages()


def _say(line: str) -> None:
    """An informative line (a result, a server event): not shown with --quiet."""
    _MESSAGES.emit("info", line)


class _ProgressBar:
    """The command's one progress bar (tqdm) on a terminal, fed as a ``progress(done, total)`` callback;
    nothing in pipes or CI. Lines said while it runs are printed above it."""

    def __init__(self, description: str, unit: str) -> None:
        self.description, self.unit = description, unit
        self.bar: Any = None  # a tqdm bar once the first report arrives
        self.json = _MESSAGES.mode == "json"
        self.enabled = self.json or (_MESSAGES.mode == "text" and sys.stderr.isatty() and not os.environ.get("CI"))
        self._last_percent = -1

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            return
        if self.json:
            percent = int(100 * done / total) if total else 100
            if percent != self._last_percent:  # at most a hundred lines, whatever the length
                self._last_percent = percent
                unit = self.unit if total == 1 else self.unit + "s"
                _MESSAGES.emit("progress", f"{self.description}: {done}/{total} {unit}", done=done, total=total)
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
            _say(line)


def _frame_progress(output: str, verb: str = "drawn") -> Callable[[int, int], None] | None:
    """A bar of frames analysed or drawn on a terminal; None in pipes or CI."""
    bar = _ProgressBar(f"{output}: frames {verb}", "frame")
    return bar if bar.enabled else None


def _forget_interrupt() -> None:
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


def _say_unshown(stream, face: str, source: str) -> None:
    """One line naming the FAPs of ``stream`` that ``face`` does not show (none: nothing said)."""
    import numpy as np

    present = [int(f) + 1 for f in np.flatnonzero(stream.mask.any(axis=0))]
    if face == "head":
        from .head.rig import head_rig

        missing = head_rig().unsupported(present)
    else:
        from .evaluation.preview import DRAWN_FAPS

        missing = [f for f in present if f not in DRAWN_FAPS]
    if missing:
        shown = "3D head" if face == "head" else "drawn face"
        _say(f"{source}: the {shown} does not show FAP {_fap_ranges(missing)} (in the stream; left out)")


def _fap_ranges(faps: list[int]) -> str:
    """[1, 2, 3, 5] -> '1-3, 5'."""
    runs: list[list[int]] = []
    for fap in sorted(faps):
        if runs and fap == runs[-1][-1] + 1:
            runs[-1].append(fap)
        else:
            runs.append([fap])
    return ", ".join(f"{run[0]}-{run[-1]}" if len(run) > 2 else ", ".join(map(str, run)) for run in runs)


def _cmd_preview(args: argparse.Namespace) -> int:
    from pathlib import Path

    from .evaluation.preview import write_preview

    _check_motion_options(args)
    audio = args.audio
    if Path(args.input).suffix.lower() == ".fap":
        from .fap.fapfile import read_fap

        stream = read_fap(args.input).stream
    elif Path(args.input).suffix.lower() in (".json", ".jsonl"):
        from .fap.exporters import read_stream_json

        stream = read_stream_json(args.input)
    else:
        from .jobs.pipeline import convert

        stream = convert(args.input, None, **_motion_kwargs(args))
        audio = audio or args.input
    if args.no_audio:
        audio = None
    scales = None
    if args.strip_scale is not None:
        import math

        from .errors import ConfigError

        try:
            brow_ens, head_deg = (float(part) for part in args.strip_scale.split(","))
        except ValueError:
            raise ConfigError(f"--strip-scale takes BROW_ENS,HEAD_DEG (e.g. 30,10), got {args.strip_scale!r}") from None
        scales = (brow_ens, math.radians(head_deg) * 1e5)
    _say_unshown(stream, args.face, args.input)
    write_preview(stream, args.output, audio=audio, width=args.width, exaggerate=args.exaggerate,
                  brow_scale=args.brow_scale, start_s=args.start, duration_s=args.duration,
                  progress=_frame_progress(args.output), scales=scales, face=args.face, strip=not args.no_strip)
    sound = " with sound" if audio is not None and Path(args.output).suffix.lower() == ".mp4" else ""
    shown = stream.duration_s - min(args.start, stream.duration_s)
    if args.duration is not None:
        shown = min(shown, args.duration)
    excerpt = f"{shown:.2f} s from {args.start:g} s" if args.start or args.duration is not None else f"{shown:.2f} s"
    _say(f"{args.output}: preview of {stream.name} ({excerpt}){sound}")
    return EXIT_OK


def _cmd_stream(args: argparse.Namespace) -> int:
    import time
    from pathlib import Path

    from audio_features.atomic import atomic_write

    from .errors import ConfigError
    from .jobs.stream import FrameRecorder, LiveConverter

    if args.mic and args.input is not None:
        raise ConfigError("give an input or --mic, not both")
    if args.input is None and not args.mic and args.listen is None:
        raise ConfigError("give an input (a file, or - for standard input), --mic, or --listen to serve the page "
                          "for browsers' microphones")
    sending = bool(args.livelink or args.vmc)
    if args.output is None and args.listen is None and not sending:
        raise ConfigError("give -o OUT (- for one JSON line per frame on standard output), --listen, --livelink "
                          "or --vmc")
    if sending and args.input is None and not args.mic:
        raise ConfigError("--livelink and --vmc send the frames of an input: give a file, - or --mic")
    if args.vmc_perfect_sync and not args.vmc:
        raise ConfigError("--vmc-perfect-sync chooses what --vmc sends; give --vmc too")
    if args.livelink_subject != "prosody" and not args.livelink:
        raise ConfigError("--livelink-subject names the stream of --livelink; give --livelink too")
    if (args.realtime or args.loop) and (args.input in (None, "-")):
        flag = "--loop plays a file again" if args.loop else "--realtime paces a file"
        raise ConfigError(f"{flag}; standard input and microphones arrive at their own pace")
    if args.loop and args.output not in (None, "-"):
        raise ConfigError("--loop never ends, so -o would never be written: watch it with --listen, or send it "
                          "with --livelink or --vmc")
    raw = args.raw_rate is not None or args.raw_format is not None or args.raw_channels is not None
    if raw and args.input != "-":
        raise ConfigError("--raw-rate, --raw-format and --raw-channels describe standard input (-): a file says "
                          "its own format")
    if args.input is None and not args.mic and args.output is not None:
        raise ConfigError("-o writes the frames of the input; with --listen alone, each browser gets the frames of "
                          "its own microphone")
    if args.format is not None and args.output in (None, "-"):
        raise ConfigError("--format names the format of an output file; -o - always writes JSON lines")
    if args.allow_origin and args.listen is None:
        raise ConfigError("--allow-origin names pages allowed to open the stream of --listen; give --listen too")
    if args.allow_origin:
        from .jobs.server import normalize_origin

        for origin in args.allow_origin:
            normalize_origin(origin)
    _check_motion_options(args)
    options = _motion_kwargs(args)
    options.pop("ground_truth")
    lookahead_ms = args.lookahead_ms

    def make_converter(rate: int) -> LiveConverter:
        return LiveConverter(rate, lookahead_ms=lookahead_ms, **options)

    # the input and the options are checked before anything listens
    reading = args.input is not None or args.mic
    senders = []
    if reading:
        rate, chunks = _stream_source(args)
        converter = make_converter(rate)
        senders = _link_senders(args, converter.fps)
    else:
        make_converter(16000)
    server = None
    requested: list = []  # expressivity a page asked for, applied between two chunks (on this thread)
    if args.listen is not None:
        from .jobs.server import FrameServer, parse_address

        host, port = parse_address(args.listen)
        server = FrameServer(host, port, make_converter=make_converter, allow_origins=args.allow_origin,
                             report=lambda line: _say(f"prosody stream: {line}"),
                             expressivity=options.get("expressivity"),
                             on_expressivity=requested.append if reading else None)
        server.start()
        _say(f"prosody stream: serving the face at {server.url} (frames over a WebSocket on the same address)")
        if reading and not args.mic and args.input != "-" and (args.realtime or args.loop):
            # a file played at its own pace is for watching: it starts when the first page is there to see it
            _say("prosody stream: the file starts when the first page connects (Ctrl-C to stop)")
            try:
                while not server.first_client.wait(0.2):
                    pass
            except KeyboardInterrupt:
                server.close()
                _say("prosody stream: stopped before any page connected")
                return EXIT_OK

    if not reading:
        try:
            while True:
                time.sleep(3600)
        except KeyboardInterrupt:
            pass
        finally:
            assert server is not None
            server.close()
        _say(f"prosody stream: stopped after serving {server.clients_served} client(s)")
        return EXIT_OK

    to_stdout = args.output == "-"
    to_file = args.output not in (None, "-")
    lines_to_file = to_file and args.output.lower().endswith(".jsonl") and args.format is None
    recorder = FrameRecorder(converter.faps) if to_file and not lines_to_file else None
    count = 0

    with contextlib.ExitStack() as outputs:
        if server is not None:
            outputs.callback(server.close)
        for sender in senders:
            outputs.callback(sender.close)
        # JSON lines go to a file as they come (renamed over OUT only when the stream ends well)
        lines = outputs.enter_context(atomic_write(args.output, newline="\n")) if lines_to_file else None

        def emit(new: list) -> None:
            nonlocal count
            if not new:
                return
            count += len(new)
            if server is not None:
                server.publish(new)
            for sender in senders:
                sender.send(new)
            text = "".join(frame.to_json() + "\n" for frame in new) if to_stdout or lines is not None else ""
            if to_stdout:
                sys.stdout.write(text)
                sys.stdout.flush()
            elif lines is not None:
                lines.write(text)
            elif recorder is not None:
                recorder.add(new)

        def consume(samples) -> None:
            while requested:
                converter.set_expressivity(requested.pop(0))
            if server is not None:
                server.publish_audio(samples, rate)
            emit(converter.push(samples))

        if args.mic or args.input == "-":  # live input: say when it is listened to (programs wait for this line)
            source = "the microphone" if args.mic else "standard input"
            _say(f"prosody stream: reading {source} at {rate} Hz (Ctrl-C to stop)")
        passes = 0
        while True:
            interrupted = _read_until_stopped(chunks, consume)
            emit(converter.finish())
            passes += 1
            if interrupted or not args.loop:
                break
            rate, chunks = _stream_source(args)  # the file again, from a fresh start
            converter = make_converter(rate)
            if server is not None:  # the controls a page may have changed meanwhile
                converter.set_expressivity(server.expressivity)
                server.restart_audio()
        if recorder is not None:
            from .fap.exporters import write_stream

            name = Path(args.input).stem if args.input not in (None, "-") else "stream"
            write_stream(recorder.stream(fps=converter.fps, name=name), args.output, args.format)
    where = "standard output" if to_stdout else (args.output or ("the clients" if server else "the links"))
    ended = "stopped by Ctrl-C or SIGTERM, the last frames flushed" if interrupted else "end of input"
    if args.loop:
        ended += f" after {passes} pass(es) of the file"
    # said once: a first sentence without a raise would otherwise look like a fault
    learning = ("; the brows rise only after the first half second of voice, which teaches them the speaker's "
                "pitch" if args.condition == "speech" and 31 in converter.faps else "")
    _say(f"prosody stream: {where}: {count} frames at {converter.fps:g} fps ({ended}; look-ahead "
         f"{converter.lookahead_frames / converter.fps * 1000:.0f} ms{learning})")
    for sender in senders:
        _say(f"prosody stream: {sender.protocol}: {sender.sent} datagram(s) sent to "
             f"{', '.join(f'{a[0]}:{a[1]}' for _, a in sender.addresses)}"
             + (f", {sender.failed} failed" if sender.failed else ""))
    return EXIT_OK


def _link_senders(args: argparse.Namespace, fps: float) -> list:
    """The stream command's UDP senders (--livelink, --vmc), their targets resolved before anything starts."""
    from .jobs.senders import LinkSender

    def report(line: str) -> None:
        _MESSAGES.emit("warning", f"prosody stream: warning: {line}")

    senders: list[LinkSender] = []
    if args.livelink:
        senders.append(LinkSender("livelink", args.livelink, fps=fps, subject=args.livelink_subject, report=report))
    if args.vmc:
        senders.append(LinkSender("vmc", args.vmc, fps=fps, perfect_sync=args.vmc_perfect_sync, report=report))
    return senders


def _read_until_stopped(chunks, consume: Callable) -> bool:
    """Feed every chunk to ``consume`` until the chunks end or Ctrl-C / SIGTERM arrives; True if stopped.

    The signal only breaks off a wait for input: a chunk being processed is finished first, so the converter
    is never left half-way through a frame and the last frames can be flushed."""
    import signal

    state = {"reading": False, "stopped": False}

    def stop(signum, frame) -> None:
        state["stopped"] = True
        if state["reading"]:
            raise KeyboardInterrupt

    previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        for sig in previous:
            signal.signal(sig, stop)
    except ValueError:  # not the main thread: signals stay as they are
        previous = {}
    iterator = iter(chunks)
    try:
        while not state["stopped"]:
            state["reading"] = True
            try:
                samples = next(iterator)
            except (StopIteration, KeyboardInterrupt):
                break
            finally:
                state["reading"] = False
            consume(samples)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return state["stopped"]


def _stream_source(args: argparse.Namespace):
    """(sample rate, chunks) of the stream command's input."""
    from audio_features.pcm import PcmFormat

    from .jobs.stream import byte_chunks, file_chunks, microphone_chunks

    if args.mic:
        return microphone_chunks(sample_rate_hz=args.mic_rate)
    if args.input == "-":
        raw = None
        if args.raw_rate is not None or args.raw_format is not None or args.raw_channels is not None:
            if args.raw_rate is None:
                from .errors import ConfigError

                raise ConfigError("raw samples on standard input need --raw-rate HZ")
            raw = PcmFormat(args.raw_rate, args.raw_format or "s16le", args.raw_channels or 1)
        return byte_chunks(sys.stdin.buffer, raw=raw, source="<stdin>")
    return file_chunks(args.input, realtime=args.realtime or args.loop)


def _cmd_train(args: argparse.Namespace) -> int:
    from .errors import ConfigError
    from .motion.training import train

    orders = {"na": args.na, "nb": args.nb, "nk": args.nk, "ridge": args.ridge}
    if args.kind in ("mouth", "live") and len(args.data) > 1:
        raise ConfigError(f"--kind {args.kind} trains on one folder; give --data once")
    if args.lookahead_ms is not None and args.kind != "live":
        raise ConfigError("--lookahead-ms sets the live head model's look-ahead: add --kind live")
    if args.kind == "mouth":
        from .motion.mouth_model import train_mouth

        given = [f"--{name}" for name, value in orders.items() if value is not None] + (["--cv"] if args.cv else [])
        if given:
            raise ConfigError(f"{', '.join(given)} do(es) not apply to the mouth model (its held-out figures come "
                              "from benchmarks/mouth_loco.py)")
        train_mouth(args.data[0], args.output, fps=args.fps, report=_say)
        return EXIT_OK
    if args.kind == "live":
        from .motion.live_training import train_live

        given = [f"--{name}" for name, value in orders.items() if value is not None]
        if given:
            raise ConfigError(f"{', '.join(given)} set(s) the ARX model's orders: add --kind arx")
        train_live(args.data[0], args.output, lookahead_ms=100.0 if args.lookahead_ms is None else args.lookahead_ms,
                   cv=args.cv, fps=args.fps, report=_say)
        return EXIT_OK
    if args.kind != "arx":
        given = [f"--{name}" for name, value in orders.items() if value is not None]
        if given:
            raise ConfigError(f"{', '.join(given)} set(s) the ARX model's orders: add --kind arx")
    from .motion.head import ARX_DEFAULTS

    orders = {name: ARX_DEFAULTS[name] if value is None else value for name, value in orders.items()}
    train(args.data, args.output, kind=args.kind, cv=args.cv, fps=args.fps,
          report=_say, **orders)
    return EXIT_OK


def _cmd_compare(args: argparse.Namespace) -> int:
    from .errors import ConfigError
    from .evaluation.compare import compare, write_comparison

    if args.transcript is not None and args.lips != "visemes":
        raise ConfigError(f"--transcript is read by the visemes; it is not used by --lips {args.lips}")
    if args.pad_map is not None and args.pad is None:
        raise ConfigError("--pad-map maps the state of --pad to the face; give --pad too")
    comparison = compare(args.input, ground_truth=args.ground_truth, model=args.model, seed=args.seed,
                         seeds=args.seeds, normalize=args.normalize, eyebrow_rule=_eyebrow_rule(args),
                         other_head_models={name: name for name in args.also_model},
                         lips=None if args.lips == "none" else args.lips, transcript=args.transcript,
                         language=args.language,
                         expression=args.expression, mouth=args.mouth, mouth_model=args.mouth_model,
                         expressivity=_expressivity(args), pad=args.pad, pad_map=args.pad_map,
                         **_analysis_kwargs(args))
    written = write_comparison(comparison, args.output, plots=args.plots, video=args.video,
                               exaggerate=args.exaggerate,
                               progress=_frame_progress(f"{args.output}/conditions.mp4") if args.video else None)
    line = f"{args.output}: {len(written)} files"
    head = comparison.metrics["conditions"]["SPEECH_DRIVEN"]["head"]
    control = comparison.metrics["controls"]["mismatched_audio"]
    if head["speed_envelope_r"] is not None:
        line += (f"; SPEECH_DRIVEN speed-envelope r {head['speed_envelope_r']:+.2f} "
                 f"(mismatched audio {control['speed_envelope_r'] or 0:+.2f}), pitch r {head['pitch_r'] or 0:+.2f} "
                 f"(mismatched audio {control['pitch_r'] or 0:+.2f})")
    _say(line)
    return EXIT_OK


def _outcome_reporter(command: str, output: str, unit: str, total: int, name: Callable[[Any], str],
                      result: Callable[[Any], str | None] | None = None) -> Callable[[Any], None]:
    """The per-input callback of a folder command (batch, track): one bar over the inputs, and each input's
    warnings and failure (always) and result line (unless quiet) said above it."""
    progress = _ProgressBar(output, unit)
    finished = [0]

    def on_outcome(outcome) -> None:
        for note in outcome.warnings:
            progress.say(f"prosody {command}: warning: {name(outcome)}: {_as_flags(str(note), command)}")
        if outcome.status == "failed":
            progress.say(f"prosody {command}: error: {name(outcome)}: {_as_flags(str(outcome.error), command)}")
        elif result is not None and (line := result(outcome)):
            progress.say(line)
        finished[0] += 1
        progress(finished[0], total)

    return on_outcome


def _cmd_batch(args: argparse.Namespace) -> int:
    from .jobs.batch import BatchOptions, find_audio_files, run_batch
    from .motion.expressivity import Expressivity

    conditions = [name for value in args.condition for name in value.split(",") if name.strip()] or None
    options = BatchOptions(model=args.model, seed=args.seed, seeds=args.seeds, normalize=args.normalize,
                           plots=args.plots, video=args.video, brows=args.brows,
                           brow_semitones=args.brow_semitones,
                           lips=None if args.lips == "none" else args.lips,
                           expressivity=(_expressivity(args) or Expressivity()).as_dict(), **_analysis_kwargs(args))
    if conditions:
        options = dataclasses.replace(options, conditions=tuple(conditions))
    on_outcome = _outcome_reporter("batch", args.output, "file", len(find_audio_files(args.input)),
                                   lambda outcome: outcome.file)

    summary = run_batch(args.input, args.output, ground_truth_dir=args.ground_truth_dir, options=options,
                        jobs=args.jobs, scheduler=args.scheduler, force=args.force, on_outcome=on_outcome)
    counts = summary["counts"]
    _say(f"{args.output}: {counts['files']} file(s), {counts['done']} processed, {counts['skipped']} already "
          f"complete, {counts['failed']} failed; summary in summary.md and summary.json")
    return EXIT_FAILURE if counts["failed"] else EXIT_OK


def _cmd_track(args: argparse.Namespace) -> int:
    from .jobs.track import TrackOptions, find_videos, track_videos

    options = TrackOptions(av_offset_ms=args.av_offset_ms, max_gap_s=args.max_gap,
                           max_side_px=None if args.max_side == 0 else args.max_side)
    from .tracking.curves import SyncEstimate

    def result(outcome) -> str | None:
        if outcome.sync is None:
            return None
        sync = SyncEstimate(**{key: outcome.sync.get(key) for key in ("lead_ms", "r", "spread_ms", "reason")})
        # the parenthesis is the clip's length, as every command's; the time taken follows it
        took = "already complete" if outcome.status == "skipped" else f"tracked in {outcome.seconds:.1f} s"
        return (f"{outcome.stem}: {outcome.frames} frames at 30 fps ({outcome.frames / 30:.1f} s), {took}; "
                f"{sync.describe()}")

    on_outcome = _outcome_reporter("track", args.output, "video", len(find_videos(args.input)),
                                   lambda outcome: outcome.video, result)

    outcomes = track_videos(args.input, args.output, options=options, audio=args.audio, jobs=args.jobs,
                            scheduler=args.scheduler, force=args.force, on_outcome=on_outcome)
    failed = sum(outcome.status == "failed" for outcome in outcomes)
    skipped = sum(outcome.status == "skipped" for outcome in outcomes)
    _say(f"{args.output}: {len(outcomes)} video(s), {len(outcomes) - failed - skipped} tracked, {skipped} already "
         f"complete, {failed} failed")
    return EXIT_FAILURE if failed else EXIT_OK


def _study_condition_names(text: str | None) -> list[str] | None:
    """--conditions of 'study plan': comma-separated names, where an item ending in .json is a conditions file
    standing for its names (in its order)."""
    if text is None:
        return None
    from .jobs.study_stimuli import read_condition_options

    names: list[str] = []
    for item in text.split(","):
        names += list(read_condition_options(item.strip())) if item.strip().lower().endswith(".json") else [item]
    return names


def _stimulus_names(given: str) -> list[str]:
    """``--stimuli``: names, comma-separated, or a folder of recordings (the stems of its WAV files)."""
    from pathlib import Path

    from .errors import ConfigError

    if not os.path.isdir(given):  # (os.path's, which says False for a name too long to be a path)
        return given.split(",")
    folder = Path(given)
    names = sorted(path.stem for path in folder.iterdir() if path.suffix.lower() == ".wav" and path.is_file())
    if not names:
        raise ConfigError(f"--stimuli {given}: a folder with no recording (NAME.wav) in it")
    return names


def _cmd_study_plan(args: argparse.Namespace) -> int:
    from .evaluation.designs import make_plan
    from .evaluation.study import write_plan

    rows = make_plan(_stimulus_names(args.stimuli), design=args.design,
                     conditions=_study_condition_names(args.conditions), seed=args.seed, repeats=args.repeats)
    write_plan(rows, args.output)
    _say(f"{args.output}: {args.design} plan, {len(rows)} presentations")
    return EXIT_OK


class _ConditionOptionsParser(_Parser):
    """Reads one study condition's convert options; a mistake is a ConfigError naming the condition."""

    def error(self, message: str) -> None:  # type: ignore[override]
        from .errors import ConfigError

        raise ConfigError(f"condition {self.prog}: {message}")


def _study_conditions(plan, path: str | None) -> dict:
    """A StudyCondition for every condition of ``plan``: the thesis's four by their options, the others from the
    conditions file."""
    import shlex

    from .errors import ConfigError
    from .jobs.study_stimuli import BUILT_IN, StudyCondition, read_condition_options

    given = read_condition_options(path) if path is not None else {}
    conditions = {}
    for name in plan.conditions:
        if name in given:
            label, options = given[name]
        elif name in BUILT_IN:
            label, options = name, BUILT_IN[name]
        else:
            raise ConfigError(f"the plan's condition {name} is not one of the thesis's four: define it in a "
                              "conditions file (--conditions FILE.json)")
        parser = _ConditionOptionsParser(prog=name, add_help=False)
        _add_motion_options(parser)
        _add_analysis_options(parser)
        _add_eyebrow_options(parser)
        try:
            words = shlex.split(options)
        except ValueError as error:
            raise ConfigError(f"condition {name}: its options cannot be read ({error})") from None
        parsed = parser.parse_args(words)
        if parsed.ground_truth is not None:
            raise ConfigError(f"condition {name}: --ground-truth is found per stimulus (<stimulus>.head.csv next to "
                              "its recording); leave it out")
        _check_motion_options(parsed)
        conditions[name] = StudyCondition(name, label, options, _motion_kwargs(parsed))
    return conditions


def _cmd_study_stimuli(args: argparse.Namespace) -> int:
    from .evaluation.designs import read_plan
    from .jobs.study_stimuli import make_stimuli

    plan = read_plan(args.plan)
    conditions = _study_conditions(plan, args.conditions)
    bar = _ProgressBar(f"{args.output}: videos", "video")
    drawn = [0]

    def on_video(stimulus: str, condition: str, made: bool) -> None:
        drawn[0] += made

    manifest = make_stimuli(plan, args.recordings, args.output, conditions, width=args.width, force=args.force,
                            on_video=on_video, progress=bar)
    kept = len(manifest["videos"]) - drawn[0]
    _say(f"{args.output}: {len(manifest['videos'])} videos of {len(plan.stimuli)} stimulus/stimuli and "
         f"{len(plan.conditions)} conditions ({drawn[0]} drawn, {kept} already complete), listed in stimuli.json")
    return EXIT_OK


def _cmd_study_serve(args: argparse.Namespace) -> int:
    import time

    from .evaluation.designs import read_plan
    from .jobs.server import parse_address
    from .jobs.study_server import StudyServer
    from .jobs.study_stimuli import check_stimuli
    from .jobs.study_store import StudyStore

    plan = read_plan(args.plan)
    host, port = parse_address(args.listen)
    check_stimuli(plan, args.stimuli)  # before the database is made: a refused start leaves nothing behind
    new = not os.path.exists(args.db)
    store = StudyStore(args.db, plan)
    try:
        try:
            server = StudyServer(plan, args.stimuli, store, host=host, port=port, break_every=args.break_every,
                                 allow_origins=args.allow_origin,
                                 report=lambda line: _say(f"prosody study serve: {line}"))
        except BaseException:
            if new:
                store.close()
                for ending in ("", "-wal", "-shm"):
                    with contextlib.suppress(FileNotFoundError):
                        os.remove(args.db + ending)
            raise
        progress = store.progress()
        _say(f"prosody study serve: the study is at {server.url} ({plan.design}, {len(plan.trials)} trials each; "
             f"{progress['participants']} participant(s) and {progress['answers']} answer(s) so far in {args.db})")
        _say(f"prosody study serve: organiser's token {server.token} (export: {server.url}admin/export.csv?token="
             f"{server.token}, or 'prosody study export {args.db} -o ballots.csv')")
        if host not in ("127.0.0.1", "::1", "localhost"):
            _say(f"prosody study serve: warning: listening on {host}: other machines can reach the study")
        server.start()
        try:
            while True:
                time.sleep(3600)
        except KeyboardInterrupt:
            pass
        finally:
            server.close()
        progress = store.progress()
        _say(f"prosody study serve: stopped; {progress['participants']} participant(s), {progress['finished']} "
             f"finished, {progress['answers']} answer(s) saved in {args.db}")
    finally:
        store.close()
    return EXIT_OK


def _cmd_study_export(args: argparse.Namespace) -> int:
    import sqlite3

    from audio_features.atomic import atomic_write

    from .errors import ConfigError
    from .jobs.study_store import StudyStore

    store = StudyStore(args.db, create=False)
    try:
        text = store.export_csv()
        progress = store.progress()
    except sqlite3.DatabaseError as error:
        raise ConfigError(f"{args.db}: the study database is damaged ({error})") from None
    finally:
        store.close()
    with atomic_write(args.output, newline="\n") as handle:
        handle.write(text)
    _say(f"{args.output}: {progress['answers']} answer(s) of {progress['participants']} participant(s) "
         f"({progress['finished']} finished), {store.design} ballots")
    return EXIT_OK


def _cmd_study_analyze(args: argparse.Namespace) -> int:
    from pathlib import Path

    from audio_features.atomic import atomic_path, atomic_write

    from .errors import BallotError
    from .evaluation import ratings
    from .evaluation.designs import read_plan
    from .evaluation.study import (
        CONDITIONS,
        analyze_ballots,
        missing_pairs,
        parse_ballots,
        read_text_file,
        study_markdown,
    )

    plan = read_plan(args.plan) if args.plan else None
    text = read_text_file(args.input)
    design = ratings.ballot_design(text)
    if plan is not None and plan.design != design:
        raise BallotError(f"{args.input}: {design} ballots, but {args.plan} is a {plan.design} plan")
    conditions = plan.conditions if plan is not None else None
    report = Path(args.report or "report.md")
    figure = report.with_name(report.stem + (".confusion.png" if design == "identification" else ".means.png"))
    draw = None  # the report's figure, drawn once everything is checked
    if design == "paired":
        ballots = parse_ballots(text, source=args.input, conditions=conditions or CONDITIONS)
        notes = missing_pairs(ballots, conditions or CONDITIONS)
        for note in notes:
            _MESSAGES.emit("warning", f"prosody study analyze: warning: {args.input}: {note}")
        results = analyze_ballots(ballots, conditions or CONDITIONS)
        summary = f"{len(ballots)} ballots, {len(results['scores'])} stimulus/stimuli"
        markdown = study_markdown(ballots, results, notes=notes, conditions=conditions or CONDITIONS) \
            if args.report else ""
        parsed: list = ballots
    elif design == "mos":
        parsed = ratings.parse_ratings(text, source=args.input, conditions=conditions)
        results = ratings.analyze_ratings(parsed, conditions)
        summary = f"{len(parsed)} ratings by {results['subjects']} subject(s)"
        markdown = ratings.ratings_markdown(results, figure=figure.name)
        draw = ratings.plot_means
    else:
        parsed = ratings.parse_identifications(text, source=args.input, classes=conditions)
        results = ratings.analyze_identifications(parsed, conditions)
        summary = (f"{len(parsed)} answers by {results['subjects']} subject(s), "
                   f"{results['overall']['accuracy']:.1%} correct (chance {results['chance']:.1%})")
        markdown = ratings.identification_markdown(results, figure=figure.name)
        draw = ratings.plot_confusion
    if plan is not None:
        strangers = [f"row {b.row} ({b.stimulus})" for b in parsed if b.stimulus not in plan.stimuli]
        if strangers:
            raise BallotError(f"{args.input}: {len(strangers)} ballot row(s) name a stimulus that is not in "
                              f"{args.plan}: " + ", ".join(strangers[:20]) + (", ..." if len(strangers) > 20 else ""))
    # every output under a temporary name, renamed only once all of them are complete
    with contextlib.ExitStack() as pending:
        handle = pending.enter_context(atomic_write(args.output, newline="\n"))
        json.dump(results, handle, indent=1, allow_nan=False)
        handle.write("\n")
        if args.report:
            if draw is not None:
                draw(results, pending.enter_context(atomic_path(figure)))
            pending.enter_context(atomic_write(args.report, newline="\n")).write(markdown)
    _say(f"{args.output}: {design} study, {summary}")
    return EXIT_OK


def _cmd_inspect(args: argparse.Namespace) -> int:
    from .fap.fapfile import read_fap
    from .fap.inspect import inspect_json, inspect_summary

    fap = read_fap(args.input, strict=args.strict)  # irregularities arrive as warnings, one line each
    if args.json:
        json.dump(inspect_json(fap), sys.stdout)
        sys.stdout.write("\n")
    else:
        print(inspect_summary(fap))
    return EXIT_OK


# parser -------------------------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="prosody",
        description="Visual prosody from speech: head and eyebrow motion (MPEG-4 FAP streams) from audio.",
        epilog="Exit codes: 0 success, 1 processing error (bad input file, failed analysis), 2 usage error.",
    )
    from . import __version__

    parser.add_argument("--version", action="version", version=f"prosody {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_Parser)

    features = commands.add_parser(
        "features", help="write F0, conditioned F0 and energy per frame to CSV",
        description="Extract Praat F0 (empty where unvoiced), the spline-conditioned F0 and Praat intensity "
                    "(dB re 2e-5 Pa) on the frame grid, one CSV row per frame: "
                    "frame,time_s,f0_hz,f0_conditioned_hz,energy_db.",
    )
    features.add_argument("input", help="audio file (WAV, FLAC, OGG, MP3, ...; mixed to mono)")
    features.add_argument("-o", "--output", required=True, help="CSV file to write (.csv), or - for standard output")
    _add_analysis_options(features)
    features.set_defaults(handler=_cmd_features)

    languages = commands.add_parser(
        "languages", help="list the transcript languages of --language (eSpeak NG's codes)",
        description="Print the language codes --language takes with a transcript, one per line with the name of "
                    "an eSpeak NG voice that speaks it: the transcript's phones come from eSpeak NG and are "
                    "aligned to the recording, so the lips articulate in any of them.")
    languages.set_defaults(handler=_cmd_languages)

    convert = commands.add_parser(
        "convert", help="turn a speech recording into a FAP stream",
        description="Compute the face's motion of one condition and write it: eyebrows (FAP 31-34), head "
                    "(48-50), lips (3-11, 16-17, 51-58: visemes from the phones heard, with coarticulation, or "
                    "--lips acoustic) and, if asked, an expression or a PAD state blended onto them. "
                    "speech: brows on pitch accents, head pitch/yaw/roll from the shipped prosodic head model "
                    "(or --model arx for the thesis's ARX model, pad for the PAD gestures, or a trained file); "
                    "random: Perlin noise; none: a still head and brows; truth: recorded motion. The lips are the "
                    "same in every condition. To see the motion, draw it with 'prosody preview'.",
    )
    convert.add_argument("input", help="speech recording")
    convert.add_argument("-o", "--output", required=True,
                         help="output file; the format follows the ending: .fap (MPEG-4), .csv (FAP units), "
                              ".json, .bvh (head joint, degrees), .livelink.csv (Live Link Face style), .glb (the "
                              "3D head animated, glTF 2.0, for Blender and three.js), .rhubarb.tsv, .rhubarb.json, "
                              ".rhubarb.xml, .dat and .prestonblair.dat (the lips as Rhubarb Lip Sync's mouth "
                              "cues, for its plugins); - writes to standard output (with --format)")
    convert.add_argument("--format", default=None,
                         choices=["fap", "csv", "csv-physical", "json", "bvh", "livelink", "gltf", "rhubarb-tsv",
                                  "rhubarb-json", "rhubarb-xml", "moho-dat", "prestonblair-dat"],
                         help="output format, overriding the ending (csv-physical: radians and fractions of "
                              "the reference distances)")
    _add_motion_options(convert)
    convert.add_argument("--base", default=None, metavar="FILE.fap",
                         help="carry this recording's other FAPs (lips, eyes) into the output")
    _add_analysis_options(convert)
    _add_eyebrow_options(convert)
    convert.set_defaults(handler=_cmd_convert)

    preview = commands.add_parser(
        "preview", help="play the motion on a 3D head, as an MP4 (with the audio) or a GIF",
        description="Animate a 3D head from one condition's stream (as 'prosody convert' makes it), from any "
                    ".fap file (Greta's, Xface's, SEMAINE's: the FAPs the head has no part for are named once), "
                    "or from this package's .json or stream .jsonl output: the head turns about the neck (FAP "
                    "48-50), the jaw, lips, lids, eyeballs, brows, cheeks, nose and tongue move by their FAPs "
                    "(3-46, 51-64) in MPEG-4's units measured on the head, the brows drawn 4 times larger unless "
                    "--brow-scale 1, all else at true scale unless --exaggerate; a strip below plots the brow and "
                    "head curves around the current frame. --face drawn shows the older drawn face (head, brows, "
                    "lips, lids), a diagnostic. .mp4 (H.264, with the recording's audio) needs ffmpeg on PATH or "
                    "the imageio-ffmpeg package; .gif (no sound, at most 1 minute at 30 fps) always works.",
    )
    preview.add_argument("input", help="speech recording, or a .fap, .json or .jsonl stream to show as it is")
    preview.add_argument("-o", "--output", required=True, metavar="OUT.mp4|OUT.gif", help="video to write")
    preview.add_argument("--audio", default=None, metavar="FILE",
                         help="sound for the MP4 when INPUT is a .fap file (default: INPUT itself if audio)")
    preview.add_argument("--no-audio", action="store_true", help="write the MP4 without sound")
    preview.add_argument("--width", type=int, default=480, metavar="PX",
                         help="frame width in pixels (default 480; the height is 5/4 of it)")
    preview.add_argument("--exaggerate", type=_exaggeration, default=1.0, metavar="X",
                         help="draw head angles and brow raises X times larger (default 1: true scale)")
    preview.add_argument("--brow-scale", type=_exaggeration, default=4.0, metavar="X",
                         help="draw the brow raises X times larger again (default 4, said on every frame: a brow "
                              "raise of speech is under a millimetre, invisible at true scale; 1: true size)")
    preview.add_argument("--face", choices=("head", "drawn"), default="head",
                         help="the 3D head (default) or the drawn diagnostic face")
    preview.add_argument("--no-strip", action="store_true", help="the face alone, without the curve strip")
    preview.add_argument("--start", type=_seconds, default=0.0, metavar="S", help="first second shown (default 0)")
    preview.add_argument("--strip-scale", default=None, metavar="BROW_ENS,HEAD_DEG",
                         help="full scale of the curve strip: brow raise in ENS and head angle in degrees (default: "
                              "this stream's largest values); give previews you compare the same scale, e.g. 30,10")
    preview.add_argument("--duration", type=_number_in(0, 1e6, low_open=True), default=None, metavar="S",
                         help="seconds shown (default: to the end)")
    _add_motion_options(preview)
    _add_analysis_options(preview)
    _add_eyebrow_options(preview)
    preview.set_defaults(handler=_cmd_preview)

    stream = commands.add_parser(
        "stream", help="animate live audio frame by frame (a pipe, a microphone, or a file), optionally served "
                       "to browsers",
        description="Compute the prosody FAPs causally, each frame as soon as the audio up to its look-ahead has "
                    "arrived: frame k (at k/fps s) uses the audio up to k/fps + the look-ahead and nothing later, "
                    "and is given out about the look-ahead plus 35 ms after its audio (plus the time the audio "
                    "takes to reach the command). The brows (accent rule by default) and the head (a live form of "
                    "the default head model, trained for that look-ahead) are those of 'convert' computed without "
                    "the future: the speaker's median pitch and level are learnt as the stream goes, so the first "
                    "second or so of voice moves little. Ends at the end of the input or on Ctrl-C, the last "
                    "frames flushed.",
    )
    stream.add_argument("input", nargs="?", default=None,
                        help="audio file, or - for standard input: a WAV stream (its header may not know the "
                             "length) or raw samples with --raw-rate")
    stream.add_argument("-o", "--output", default=None,
                        help="- writes one JSON line per frame to standard output as each frame is ready: "
                             '{"frame": k, "time_s": t, "faps": {"31": v, ..., "50": v}} (FAP units; channels that '
                             "are off are absent); a file (.fap, .csv, .json, .bvh, .livelink.csv, .jsonl) is "
                             "written when the stream ends")
    stream.add_argument("--format", default=None,
                        choices=["fap", "csv", "csv-physical", "json", "bvh", "livelink"],
                        help="format of the output file, overriding its ending")
    stream.add_argument("--lookahead-ms", type=_lookahead, default=100.0, metavar="MS",
                        help="audio after each frame that the frame may use, in ms (default 100: the most that "
                             "keeps the median delay near 150 ms; more makes the head follow the speech better, "
                             "0 gives the least delay; rounded to whole frames)")
    source = stream.add_argument_group("input")
    source.add_argument("--mic", action="store_true",
                        help="read the default microphone (needs the sounddevice package: "
                             "pip install 'visual-prosody[mic]')")
    source.add_argument("--mic-rate", type=_sample_rate, default=16000, metavar="HZ",
                        help="sample rate asked of the microphone (default 16000)")
    source.add_argument("--loop", action="store_true",
                        help="play the file again and again at its own pace until Ctrl-C (a demo for --listen, "
                             "--livelink or --vmc); with --listen it starts when the first page connects")
    source.add_argument("--realtime", action="store_true",
                        help="read a file no faster than it plays (a demo of live input)")
    source.add_argument("--raw-rate", type=_sample_rate, default=None, metavar="HZ",
                        help="standard input holds raw samples at HZ instead of a WAV stream")
    source.add_argument("--raw-format", default=None, choices=["s16le", "s24le", "s32le", "f32le", "f64le", "u8"],
                        help="sample format of raw input (default s16le: 16-bit signed little-endian)")
    source.add_argument("--raw-channels", type=_whole_number(1, 64, "1 to 64"), default=None, metavar="N",
                        help="interleaved channels of raw input, mixed to mono (default 1)")
    stream.add_argument("--listen", default=None, metavar="HOST:PORT",
                        help="also serve the frames over a WebSocket, and at http://HOST:PORT/ a page that draws "
                             "the face moving with them and can send the browser's microphone (127.0.0.1 when "
                             "HOST is left out; another address lets anyone who can reach it watch the stream and "
                             "send audio to this machine); port 0 picks a free one")
    stream.add_argument("--allow-origin", action="append", default=[], metavar="ORIGIN",
                        help="with --listen: also let pages from ORIGIN (http(s)://HOST[:PORT]) open the stream; "
                             "by default only the page served at --listen's own address may (repeatable)")
    links = stream.add_argument_group(
        "sending to animation tools", "each frame of the input is sent over UDP as soon as it is ready; a tool "
        "that is not listening loses those frames (said once)")
    links.add_argument("--livelink", action="append", default=[], metavar="HOST[:PORT]",
                       help="send Live Link Face packets, as the iPhone app does, to Unreal's Live Link at "
                            "HOST (port 11111 unless given; repeatable): 52 ARKit blendshapes and the head's "
                            "yaw, pitch and roll in radians")
    links.add_argument("--livelink-subject", default="prosody", metavar="NAME",
                       help="the subject name Unreal lists the stream under (default prosody)")
    links.add_argument("--vmc", action="append", default=[], metavar="HOST[:PORT]",
                       help="send the VMC protocol (OSC) to a marionette such as VSeeFace, VMagicMirror or "
                            "Warudo at HOST (port 39539 unless given; repeatable): the Head bone's rotation and "
                            "VRM's A I U E O and blink presets")
    links.add_argument("--vmc-perfect-sync", action="store_true",
                       help="send the 52 ARKit blendshapes of 'perfect sync' avatars instead of VRM's presets "
                            "(VRM's presets have no brows: this is how the brows reach such an avatar)")
    _add_motion_options(stream, live=True)
    _add_analysis_options(stream)
    _add_eyebrow_options(stream)
    stream.set_defaults(handler=_cmd_stream)

    train = commands.add_parser(
        "train", help="train a head-motion model on paired recordings",
        description="Fit a head model on every <name>.wav in DIR that has a <name>.head.csv (columns "
                    "frame,time_s,rx_rad,ry_rad,rz_rad at 30 fps) or a <name>.fap beside it. A pair whose "
                    "durations differ by more than two frames is reported and skipped. --kind prosodic (the "
                    "default) learns how much the head moves and how it nods from the speech, and the size and "
                    "tempo of the recorded motion; --kind arx fits the thesis's linear ARX model; --kind live fits "
                    "the causal form of the prosodic model for 'prosody stream'. Use the file with --model in "
                    "convert, compare, batch and preview (live models: in stream).",
    )
    train.add_argument("--data", required=True, action="append", metavar="DIR",
                       help="folder of paired recordings (<name>.wav with <name>.head.csv or .fap, as 'prosody "
                            "track' writes them); repeat it to train on several. A speakers.csv (columns "
                            "recording,speaker) in a folder makes --cv hold out a speaker's recordings together")
    train.add_argument("-o", "--output", required=True, help="model file to write (.json)")
    train.add_argument("--kind", default="prosodic", choices=["prosodic", "arx", "pad", "live", "mouth"],
                       help="which model to fit (default prosodic; pad: seed 000's gestures with Eq. 2's arousal "
                            "coefficients fitted to the recordings' amplitude per prosodic word, for --model FILE; "
                            "live: the causal form of the prosodic model "
                            "that 'prosody stream' uses, trained on the audio analysed as a stream; mouth: the "
                            "acoustic mouth model of --lips acoustic, on <name>.wav + <name>.mouth.csv pairs)")
    train.add_argument("--lookahead-ms", type=_lookahead, default=None, metavar="MS",
                       help="--kind live: audio after each frame the model reads, in ms (default 100); stream "
                            "with at least this --lookahead-ms")
    train.add_argument("--cv", action="store_true",
                       help="leave-one-speaker-out cross-validation (a folder's speakers.csv names the speakers; "
                            "without one, each recording is its own): for prosodic, choose its settings by the "
                            "held-out speed-envelope and pitch correlations above the mismatched-audio control "
                            "and store those figures in the model file (pitch share, speed passes, envelope power, "
                            "pitch follow); for live, its presence window or pitch follow the same way; for arx, "
                            "choose na, nb, nk and the ridge penalty by free-run error (the head measures are "
                            "reported beside it)")
    arx = train.add_argument_group("ARX orders (--kind arx only)")
    arx.add_argument("--na", type=int, default=None, help="past outputs fed back (default 1)")
    arx.add_argument("--nb", type=int, default=None, help="input lags (default 5)")
    arx.add_argument("--nk", type=int, default=None, help="input delay in frames (default 0)")
    arx.add_argument("--ridge", type=_number_in(0, 1e6), default=None, metavar="R",
                     help="ridge penalty, 0 to 1e6 (default 0.1)")
    train.add_argument("--fps", type=_number_in(1, 1000), default=DEFAULT_FPS,
                       help=f"frame rate (default {DEFAULT_FPS:g}, 1 to 1000)")
    train.set_defaults(handler=_cmd_train)

    compare = commands.add_parser(
        "compare", help="compare the four conditions on one recording (FAP files, plots, report, metrics)",
        description="Write OUTDIR/no_prosody.fap, random.fap, speech_driven.fap (and ground_truth.fap with "
                    "--ground-truth), features.png and head.png, report.md and metrics.json. With recorded motion, "
                    "the report leads with the head measures of each condition: speed-envelope r (does the head "
                    "move when the recording moves), pitch r, the spread of each axis as a ratio to the "
                    "recording's, and the velocity-spectrum distance (too still or too jittery), beside the "
                    "speech-driven generator driven by this recording's audio shifted in time (a control that "
                    "keeps the audio's statistics but not its timing); then the brows against recorded brows "
                    "(<clip>.brows.csv beside the .head.csv), statistics per FAP, Pearson r and RMSE, and "
                    "canonical correlations. Random and speech-driven measures are averaged over --seeds seeds.",
    )
    compare.add_argument("input", help="speech recording")
    compare.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output folder (created)")
    compare.add_argument("--ground-truth", default=None, metavar="FILE",
                         help="recorded motion: <clip>.head.csv or .fap (enables GROUND_TRUTH and agreement)")
    _add_generator_options(compare)
    _add_seeds_option(compare)
    compare.add_argument("--also-model", action="append", default=[], metavar="NAME|FILE",
                         help="measure another head model beside the speech-driven one, with its own control "
                              "(e.g. --also-model arx: the thesis's model next to the default; repeatable); its "
                              "speech-driven stream is written as speech_driven.<NAME>.fap and gets a panel in "
                              "--video")
    compare.add_argument("--normalize", action="store_true",
                         help="scale and offset RANDOM, SPEECH_DRIVEN and GROUND_TRUTH to the same mean and "
                              "standard deviation per FAP (the ground truth's where it has the FAP), as the "
                              "thesis's second experiment did")
    compare.add_argument("--plots", action=argparse.BooleanOptionalAction, default=True,
                         help="write the PNG figures (default; --no-plots skips them), as batch --plots")
    compare.add_argument("--video", action="store_true",
                         help="also write OUTDIR/conditions.mp4: the conditions' faces side by side, labelled, "
                              "with the recording's audio (needs ffmpeg or the imageio-ffmpeg package)")
    compare.add_argument("--mouth", default=None, metavar="FILE.mouth.csv",
                         help="a video-tracked mouth for the lip measures (default: the <clip>.mouth.csv beside "
                              "the ground truth or the audio, if any)")
    _add_face_options(compare)
    _add_expressivity_options(compare)
    compare.add_argument("--exaggerate", type=_exaggeration, default=1.0, metavar="X",
                         help="with --video: draw head angles and brow raises X times larger (default 1)")
    _add_analysis_options(compare)
    _add_eyebrow_options(compare)
    compare.set_defaults(handler=_cmd_compare)

    batch = commands.add_parser(
        "batch", help="convert and compare every audio file of a folder tree",
        description="Process every audio file under INDIR (recursively) into OUTDIR/<relative folder>/<stem>/ "
                    "(condition .fap files and metrics.json; figures and report with --plots), comparing with "
                    "ground truth where <stem>.head.csv or <stem>.fap is found in --ground-truth-dir (same "
                    "relative path, or its top). Writes OUTDIR/summary.md and summary.json. A broken file is "
                    "reported and skipped; the exit code is 1 if any failed. Re-running skips complete outputs "
                    "made with the same settings.",
    )
    batch.add_argument("input", metavar="INDIR", help="folder of recordings")
    batch.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output folder (created)")
    batch.add_argument("--ground-truth-dir", default=None, metavar="DIR", help="folder of recorded motion")
    batch.add_argument("--condition", action="append", default=[], metavar="NAME[,NAME]",
                       help="conditions to produce: none, random, speech, truth (repeatable; default all, truth "
                            "only where found)")
    batch.add_argument("--jobs", type=int, default=1, help="local worker processes (default 1)")
    batch.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="run on a Dask distributed cluster, e.g. tcp://host:8786 (needs the 'cluster' extra)")
    _add_generator_options(batch)
    _add_seeds_option(batch)
    batch.add_argument("--lips", default="visemes", choices=["visemes", "acoustic", "none"],
                       help="how the lips move, alike in every condition (default visemes; see convert --help); "
                            "with a <clip>.mouth.csv beside the ground truth, the lips are measured against it")
    batch.add_argument("--brows", default="accent", choices=["accent", "thesis"],
                       help="eyebrow rule of the speech-driven condition, with its default settings (default "
                            "accent; thesis: the thesis's 207 Hz / 45 dB rule)")
    batch.add_argument("--brow-semitones", type=_number_in(0, 24, low_open=True), default=None, metavar="ST",
                       help="semitones above the speaker's median pitch that raise the brows, for either rule "
                            "(default: the rule's own, 4 for the accent rule; lower raises more often)")
    batch.add_argument("--normalize", action="store_true", help="normalise as 'prosody compare --normalize'")
    batch.add_argument("--plots", action=argparse.BooleanOptionalAction, default=False,
                       help="also write figures and a report per file (default --no-plots, for speed)")
    batch.add_argument("--video", action="store_true",
                       help="also write each file's conditions.mp4, as compare --video (needs ffmpeg or the "
                            "imageio-ffmpeg package)")
    batch.add_argument("--force", action="store_true", help="redo files whose outputs are already complete")
    _add_expressivity_options(batch)
    _add_analysis_options(batch)
    batch.set_defaults(handler=_cmd_batch)

    track = commands.add_parser(
        "track", help="track talking-head videos into head, brow and mouth curves (the files train and compare "
                      "read)",
        description="Run a face tracker (MediaPipe FaceLandmarker) on each video and write, into OUTDIR, "
                    "<stem>.wav (its sound, 16 kHz mono), <stem>.head.csv, <stem>.brows.csv and <stem>.mouth.csv "
                    "(30 fps, frame k at k/30 s of the sound; empty cells where the face is not found) and "
                    "<stem>.track.json (what was done, and how the mouth's motion lines up with the sound). "
                    "Folders are searched for videos recursively. With several faces in view, the largest one of "
                    "the first frame is followed. A video without sound takes the WAV of the same name beside it. "
                    "Complete outputs are skipped on a re-run. Needs: pip install 'visual-prosody[track]'.",
    )
    track.add_argument("input", nargs="+", metavar="VIDEO", help="video files or folders of them")
    track.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output folder (created)")
    track.add_argument("--audio", default=None, metavar="FILE",
                       help="the sound of a single video that has none (default: <stem>.wav beside it, if any)")
    track.add_argument("--av-offset-ms", type=_number_in(-5000, 5000), default=0.0, metavar="MS",
                       help="move the motion this many ms later against the sound (negative: earlier), for a "
                            "video whose picture runs ahead of its sound (default 0; track.json gives an estimate)")
    track.add_argument("--max-gap", type=_number_in(0, 10), default=0.25, metavar="S",
                       help="bridge stretches without the face up to S seconds by interpolation; longer ones stay "
                            "empty (default 0.25)")
    track.add_argument("--max-side", type=_whole_number(0, 8192, "0 to 8192"), default=1280, metavar="PX",
                       help="scale frames larger than PX down before tracking (default 1280; 0 keeps them)")
    track.add_argument("--jobs", type=int, default=1, help="local worker processes (default 1)")
    track.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="run on a Dask distributed cluster (scheduler address), as batch")
    track.add_argument("--force", action="store_true", help="redo videos whose outputs are already complete")
    track.set_defaults(handler=_cmd_track)

    study = commands.add_parser(
        "study", help="run a perceptual study: plan it, make its videos, serve its page, export and analyse answers",
        description="A perceptual study from plan to analysis. 'plan' writes the presentation order of one of three "
                    "designs (paired comparisons as the thesis, 1-5 opinion scores as seed 000, identification as "
                    "seed 002); 'stimuli' draws the face video of every stimulus and condition; 'serve' runs the "
                    "study's page and saves every answer in an SQLite database; 'export' writes the answers as "
                    "ballots; 'analyze' runs the design's statistics.",
    )
    study_commands = study.add_subparsers(dest="study_command", required=True, metavar="STEP",
                                          parser_class=_Parser)
    plan = study_commands.add_parser(
        "plan", help="write the randomised presentation order",
        description="paired (default): every ordered pair of the conditions per stimulus (with the thesis's four, "
                    "16 pairs, same-model pairs included, so each condition is left 4 times and right 4 times), in "
                    "rounds that show one pair of every stimulus in shuffled order; CSV columns "
                    "order,stimulus,left,right. mos: every condition of every stimulus --repeats times, in rounds; "
                    "columns order,stimulus,condition. identification: the same, columns order,stimulus,shown; the "
                    "answer options are the conditions. The same seed gives the same plan; 'serve' gives each "
                    "participant their own order from it.",
    )
    plan.add_argument("--stimuli", required=True, metavar="NAME[,NAME...]|DIR",
                      help="stimulus names, comma-separated (each the name of a recording: NAME.wav), or the "
                           "folder of the recordings (every NAME.wav in it), as 'study stimuli --recordings' takes")
    plan.add_argument("--design", choices=["paired", "mos", "identification"], default="paired",
                      help="paired comparison (default), opinion scores 1-5, or identification")
    plan.add_argument("--conditions", default=None, metavar="NAME|FILE.json,...",
                      help="the conditions compared (default: none,random,speech,truth, the thesis's four; "
                           "identification needs its own): names, comma-separated; an item ending in .json is a "
                           "conditions file and stands for the conditions it defines (see 'study stimuli')")
    plan.add_argument("--repeats", type=_whole_number(1, 100, "1 to 100"), default=1, metavar="N",
                      help="mos and identification: show each condition of each stimulus N times (default 1)")
    plan.add_argument("--seed", type=_seed, default=0, help="seed of the order (a whole number >= 0, default 0)")
    plan.add_argument("-o", "--output", required=True, help="plan CSV to write")
    plan.set_defaults(handler=_cmd_study_plan)

    stimuli = study_commands.add_parser(
        "stimuli", help="draw the video of every stimulus and condition of a plan",
        description="For every stimulus and condition of PLAN, the 3D head animated by that condition with the "
                    "recording's audio, as OUT/<stimulus>/<condition>.mp4 (no curve strip and no caption, so nothing "
                    "on screen names the condition), with the same frames for the ballot's WebGL head as "
                    "OUT/<stimulus>/<condition>.head.json, listed in OUT/stimuli.json. Recordings are RECORDINGS/"
                    "<stimulus>.wav (or another audio ending), with <stimulus>.head.csv (or .fap) for the truth "
                    "condition. The thesis's four conditions need no definition; others are defined in a JSON file: "
                    '{"format": "visual-prosody-study-conditions", "version": 1, "conditions": {"calm": {"label": '
                    '"Calm", "options": "--activation 0.4 --pad 0.5,-0.3,0"}}}, where options are any of '
                    "'prosody convert''s motion, face, expressivity and analysis options. Videos already made with "
                    "the same settings are kept; MP4 needs ffmpeg (or the imageio-ffmpeg package).",
    )
    stimuli.add_argument("plan", metavar="PLAN.csv", help="the study's plan")
    stimuli.add_argument("--recordings", required=True, metavar="DIR", help="folder of <stimulus>.wav recordings")
    stimuli.add_argument("--conditions", default=None, metavar="FILE.json",
                         help="definitions of the plan's conditions other than the thesis's four")
    stimuli.add_argument("--width", type=_whole_number(64, 1920, "64 to 1920"), default=480, metavar="PX",
                         help="video width in pixels (the face is square; default 480)")
    stimuli.add_argument("--force", action="store_true", help="draw every video again")
    stimuli.add_argument("-o", "--output", required=True, metavar="DIR", help="folder of the videos")
    stimuli.set_defaults(handler=_cmd_study_stimuli)

    serve = study_commands.add_parser(
        "serve", help="serve the study's page to participants and save their answers",
        description="Serves a page (nothing loaded from other sites) where each participant gets an anonymous ID, "
                    "watches every trial of PLAN in their own counterbalanced order (sequence reshuffled per "
                    "participant, sides swapped for every second one), answers, gets a break every --break-every "
                    "trials, and a completion code at the end. Every answer is one SQLite transaction (WAL) in "
                    "--db: a crash, a restart or a closed tab loses nothing, a participant resumes where they "
                    "stopped (same browser, or /?participant=ID), a repeated submission counts once. Restart with "
                    "the same --db to go on. Only this server's own page may use it. Prints the organiser's token "
                    "for /admin/export.csv and /admin/progress.",
    )
    serve.add_argument("plan", metavar="PLAN.csv", help="the study's plan")
    serve.add_argument("--stimuli", required=True, metavar="DIR", help="the videos made by 'prosody study stimuli'")
    serve.add_argument("--db", required=True, metavar="study.sqlite",
                       help="the answers' database (made if missing; must be of this plan)")
    serve.add_argument("--listen", default="127.0.0.1:8766", metavar="HOST:PORT",
                       help="address to serve on (default 127.0.0.1:8766, this machine only; 0.0.0.0:PORT opens it "
                            "to the network)")
    serve.add_argument("--break-every", type=_whole_number(0, 10000, "0 to 10000"), default=20, metavar="N",
                       help="a break screen every N trials (default 20; 0: none)")
    serve.add_argument("--allow-origin", action="append", default=[], metavar="ORIGIN",
                       help="also let pages from ORIGIN (http(s)://HOST[:PORT]) use the study (repeatable)")
    serve.set_defaults(handler=_cmd_study_serve)

    export = study_commands.add_parser(
        "export", help="write the answers of a study database as ballots",
        description="Writes every answer in DB, once, as the ballots 'study analyze' reads: paired "
                    "stimulus,subject,left,right,choice; mos stimulus,subject,condition,score; identification "
                    "stimulus,subject,shown,answer; each with order (the plan's trial number). The subject is the "
                    "participant's anonymous ID. Safe while the server runs.",
    )
    export.add_argument("db", metavar="study.sqlite", help="the study's database")
    export.add_argument("-o", "--output", required=True, metavar="BALLOTS.csv", help="ballots to write")
    export.set_defaults(handler=_cmd_study_export)

    analyze = study_commands.add_parser(
        "analyze", help="analyse a study's ballots (the design is read from their columns)",
        description="paired (stimulus,subject,left,right,choice): scores, and one paired t-test of per-subject "
                    "scores per pair of conditions and stimulus (a minus b, 95% CI, two-tailed p, p_holm: "
                    "Holm-corrected over the stimulus's tests). mos (stimulus,subject,condition,score): means with "
                    "95% CIs, one-way ANOVA (F, df, p, eta and omega squared), repeated-measures ANOVA over the "
                    "subjects who rated every condition (partial eta squared), Tukey's pairwise tests with Cohen's "
                    "d. identification (stimulus,subject,shown,answer): accuracy per class with exact 95% CIs and "
                    "one-sided binomial tests against chance (Holm-corrected), and the confusion matrix. Bad rows "
                    "are reported by line number. --report also writes the figure beside it.",
    )
    analyze.add_argument("input", metavar="BALLOTS.csv", help="ballot file")
    analyze.add_argument("-o", "--output", required=True, metavar="results.json", help="results to write")
    analyze.add_argument("--plan", default=None, metavar="PLAN.csv",
                         help="the study's plan: its conditions are the ones ballots may name (needed for paired "
                              "studies of conditions other than the thesis's four)")
    analyze.add_argument("--report", default=None, metavar="OUT.md",
                         help="also write a readable report, and its figure (OUT.means.png or OUT.confusion.png)")
    analyze.set_defaults(handler=_cmd_study_analyze)

    inspect = commands.add_parser(
        "inspect", help="describe a .fap file (or print it as JSON)",
        description="Read a .fap file liberally and describe it; irregularities are reported on stderr.",
    )
    inspect.add_argument("input", help=".fap file")
    inspect.add_argument("--strict", action="store_true",
                         help="refuse an irregular file (comments, 69-token masks, renumbered frames, ...) instead "
                              "of reading it with a warning for each irregularity")
    inspect.add_argument("--json", action="store_true",
                         help='print {"version", "name", "fps", "frames", "faps": {"<n>": [value or null, ...]}}')
    inspect.set_defaults(handler=_cmd_inspect)
    _add_message_options(parser)
    return parser


def _add_message_options(parser: argparse.ArgumentParser) -> None:
    """--quiet and --messages json on every command (after its name, as its other options)."""
    subparsers = [action for action in parser._actions if isinstance(action, argparse._SubParsersAction)]
    if not subparsers:
        group = parser.add_argument_group("messages")
        group.add_argument("-q", "--quiet", action="store_true",
                           help="say nothing but errors on stderr (no progress, no warnings, no result lines)")
        group.add_argument("--messages", choices=["text", "json"], default="text",
                           help="json: one JSON object per line on stderr ({\"event\": \"progress\"|\"info\"|"
                                "\"warning\"|\"error\", \"message\", ...}), for programs that drive the command")
        return
    for action in subparsers:
        for sub in action.choices.values():
            _add_message_options(sub)


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


def _as_flags(message: str, command: str | None = None) -> str:
    """A library message with its Python argument names replaced by the command's options."""
    for python, flag in (_BATCH_FLAGS + _FLAGS if command == "batch" else _FLAGS):
        message = message.replace(python, flag)
    return message


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
        from .evaluation.compare import OUTPUT_NAMES

        extra = ("summary.json", "summary.md", "features.csv") if command == "batch" else ()
        return name in (*OUTPUT_NAMES, *extra) or fnmatch.fnmatch(name, "speech_driven.*.fap")
    if command == "study":
        return name == "stimuli.json" or name.endswith(".mp4")
    return False


def _flag_of(name: str) -> str:
    return "the input" if name == "input" else "-o" if name == "output" else f"--{name.replace('_', '-')}"


def _check_paths(args: argparse.Namespace) -> None:
    """Refuse outputs that would destroy an input or each other, empty names, and - where it is no stream."""
    from .errors import ConfigError

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


def _run(handler: Callable[[argparse.Namespace], int], args: argparse.Namespace) -> int:
    from .errors import ParameterError, VisualProsodyError

    try:
        _check_paths(args)
        return handler(args)
    except ParameterError as error:  # prosody's ConfigError too
        _MESSAGES.emit("error", f"prosody {args.command}: error: {_as_flags(str(error))}", exit=EXIT_USAGE)
        return EXIT_USAGE
    except VisualProsodyError as error:
        _MESSAGES.emit("error", f"prosody {args.command}: error: {_as_flags(str(error))}", exit=EXIT_FAILURE)
        return EXIT_FAILURE
    except BrokenPipeError:
        raise  # the reader of our output went away: main() ends quietly
    except OSError as error:
        where = f"{error.filename}: " if error.filename else ""
        _MESSAGES.emit("error", f"prosody {args.command}: error: {where}{error.strerror or error}",
                       exit=EXIT_FAILURE)
        return EXIT_FAILURE


def main(argv: Sequence[str] | None = None) -> int:
    """The ``prosody`` command. Called from Python (a test, a notebook), it leaves the process as it found it:
    the message mode, the SIGTERM handler and a closed standard error are restored when it returns."""
    import signal
    import warnings

    parser = build_parser()
    args = parser.parse_args(argv)
    mode = _MESSAGES.mode
    stderr = sys.stderr
    previous: Any = None
    try:
        if sys.stderr is None:  # started with standard error closed (2>&-): messages go nowhere, work goes on
            sys.stderr = open(os.devnull, "w")  # noqa: SIM115 - closed below
        _MESSAGES.mode = "json" if getattr(args, "messages", None) == "json" else (
            "quiet" if getattr(args, "quiet", False) else "text")

        def show(message, category, filename, lineno, file=None, line=None):
            # a warning is a note to the user, one line, not a source listing
            _MESSAGES.emit("warning", f"prosody {args.command}: warning: {_as_flags(str(message))}")

        def terminated(signum, frame):
            # SIGTERM unwinds like Ctrl-C, so that temporary files are removed and nothing is left half-written
            raise KeyboardInterrupt

        with contextlib.suppress(ValueError):  # only the main thread may set handlers
            previous = signal.signal(signal.SIGTERM, terminated)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("default")
                warnings.showwarning = show
                return _run(args.handler, args)
        except KeyboardInterrupt:
            _MESSAGES.emit("error", f"prosody {args.command}: interrupted", exit=130)
            _forget_interrupt()
            return 130
        except BrokenPipeError:
            # the reader went away (`prosody inspect F.fap | head -1`): not an error of ours
            with contextlib.suppress(OSError):
                devnull = os.open(os.devnull, os.O_WRONLY)
                os.dup2(devnull, sys.stdout.fileno())
            return EXIT_OK
    finally:
        if previous is not None:
            with contextlib.suppress(ValueError):
                signal.signal(signal.SIGTERM, previous)
        _MESSAGES.mode = mode
        if stderr is None and sys.stderr is not None:
            sys.stderr.close()
            sys.stderr = stderr


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
