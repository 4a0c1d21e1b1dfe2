"""Option groups, argument types and the checks shared by the commands that make motion."""

from __future__ import annotations

import argparse
from collections.abc import Callable

from audio_features.defaults import DEFAULT_F0_CEILING_HZ, DEFAULT_F0_FLOOR_HZ, DEFAULT_FPS


class Parser(argparse.ArgumentParser):
    """argparse with the package's one-line error style (exit code 2)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


EXIT_OK, EXIT_FAILURE, EXIT_USAGE = 0, 1, 2


def positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value > 0 or value != value or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def whole_number(low: int, high: int, shown: str) -> Callable[[str], int]:
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


def lookahead(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of milliseconds, got {text!r}") from None
    if not 0 <= value <= 2000:
        raise argparse.ArgumentTypeError(f"expected milliseconds from 0 to 2000, got {text!r}")
    return value


seed = whole_number(0, 2**63 - 1, "0 to 2**63-1")


def number_in(low: float, high: float, *, low_open: bool = False) -> Callable[[str], float]:
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
exaggeration = number_in(0, 100, low_open=True)


#: Times within a recording, in s (a million seconds: eleven days).
seconds = number_in(0, 1e6)


seeds = whole_number(1, 1000, "1 to 1000")


sample_rate = whole_number(8000, 768000, "8000 to 768000 (Hz)")


def add_seeds_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seeds", type=seeds, default=10, metavar="N",
                        help="average the measures of the random and speech-driven conditions (and of the "
                             "control) over N seeds from --seed on (default 10); the written streams use --seed")


def add_analysis_options(parser: argparse.ArgumentParser, *, cues: bool = False) -> None:
    """The analysis options; with ``cues``, ``--fps`` left out means the library's choice (30, or 100 for the
    mouth cues' formats)."""
    default = "30; 100 for the mouth cues' formats, Rhubarb's 0.01 s grid" if cues else "30"
    parser.add_argument("--fps", type=number_in(1, 1000), default=None if cues else DEFAULT_FPS,
                        help=f"frames per second of the output grid (default {default}; 1 to 1000; frame k is at "
                             "k/fps s)")
    parser.add_argument("--f0-floor", dest="f0_floor_hz", type=positive_float, default=DEFAULT_F0_FLOOR_HZ,
                        metavar="HZ",
                        help=f"lowest F0 the pitch tracker looks for, in Hz (default {DEFAULT_F0_FLOOR_HZ:g})")
    parser.add_argument("--f0-ceiling", dest="f0_ceiling_hz", type=positive_float, default=DEFAULT_F0_CEILING_HZ,
                        metavar="HZ",
                        help=f"highest F0 the pitch tracker looks for, in Hz (default {DEFAULT_F0_CEILING_HZ:g})")


def add_generator_options(parser: argparse.ArgumentParser, *, live: bool = False) -> None:
    if live:
        parser.add_argument("--model", default=None, metavar="NAME|FILE",
                            help="live head model: 'prosodic' (the default: the shipped live head that reads the "
                                 "most within --lookahead-ms) or a file from 'prosody train --kind live'; 'arx' "
                                 "and 'pad' need whole recordings and are not offered live")
    else:
        parser.add_argument("--model", default=None, metavar="NAME|FILE",
                            help="head model for the speech-driven condition: 'prosodic' (the default: motion of "
                                 "a person's size timed by the speech), 'arx' (the thesis's linear model), 'pad' "
                                 "(Jia et al.'s nod per prosodic word), 'pad-random' (its random baseline), or a "
                                 "file from 'prosody train'")
    parser.add_argument("--seed", type=seed, default=0,
                        help="seed of the random condition and of the speech-driven head's motion (a whole "
                             "number >= 0, default 0: the same seed gives the same stream)")


def add_motion_options(parser: argparse.ArgumentParser, *, live: bool = False) -> None:
    """Condition, generator and intensity options of the commands that make one stream (convert, preview,
    and without recorded motion, stream)."""
    from ..motion.conditions import CONDITION_NAMES, LIVE_CONDITION_NAMES
    parser.add_argument("--condition", default="speech",
                        choices=LIVE_CONDITION_NAMES if live else CONDITION_NAMES,
                        help="which animation to produce (default speech)")
    if not live:
        parser.add_argument("--ground-truth", default=None, metavar="FILE",
                            help="recorded motion for --condition truth: <clip>.head.csv or .fap")
    add_generator_options(parser, live=live)
    add_channel_options(parser)
    add_expressivity_options(parser)
    if live:
        from ..motion.face.expressions import EXPRESSIONS

        parser.add_argument("--lips", dest="live_lips", default="acoustic", choices=["acoustic", "none"],
                            help="lips from the live acoustic mouth model (default; the same in every condition), "
                                 "or none; the visemes of convert need whole phones and their neighbours, so they "
                                 "and --transcript (aligned to the whole recording) are not offered live")
        parser.add_argument("--expression", default=None, metavar="NAME[:INTENSITY]|FILE.csv",
                            help=f"a facial expression over the stream ({', '.join(EXPRESSIONS)}; intensity 0-1, "
                                 "default 1), or a CSV file of timed ones (start_s,end_s,expression,intensity, "
                                 "times from the stream's start), mixed with the lips as in convert")
    else:
        add_face_options(parser)


def add_channel_options(parser: argparse.ArgumentParser) -> None:
    """The gains and channels left out (the library's :class:`~prosody.motion.settings.ChannelSettings`)."""
    from ..motion.settings import MAX_GAIN

    controls = parser.add_argument_group("intensity (1 keeps the motion as computed, 0.5 halves it)")
    for channel, what in (("pitch", "head nods (FAP 48)"), ("yaw", "head turns (FAP 49)"),
                          ("roll", "head tilts (FAP 50)"), ("brow", "eyebrow raises (FAP 31-34)")):
        controls.add_argument(f"--{channel}-gain", type=number_in(0, MAX_GAIN), default=1.0, metavar="G",
                              help=f"scale the {what} by G (default 1; 0 to 100, the head and brows kept within "
                                   "what a person can do)")
    controls.add_argument("--lip-gain", type=number_in(0, MAX_GAIN), default=1.0, metavar="G",
                          help="scale the lips' motion (FAP 3-11, 16-17, 51-58) by G (default 1)")
    controls.add_argument("--off", dest="disabled", action="append", default=[], metavar="CHANNEL[,CHANNEL]",
                          help="leave channels out of the output: pitch, yaw, roll, brows, lips (repeatable)")


def channel_kwargs(args: argparse.Namespace) -> dict:
    """The ``gains`` and ``disabled`` keywords set by :func:`add_channel_options`."""
    gains = {"pitch": args.pitch_gain, "yaw": args.yaw_gain, "roll": args.roll_gain, "brows": args.brow_gain,
             "lips": args.lip_gain}
    return {"gains": gains, "disabled": [name.strip() for value in args.disabled for name in value.split(",")
                                         if name.strip()]}


def add_expressivity_options(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group(
        "expressivity", "Greta's six expressivity parameters, on every head and brow generator alike (the "
        "speech-driven head of any --model, the brows of either rule, the random condition, and live). The "
        "defaults leave the motion as generated.")
    group.add_argument("--activation", type=number_in(0, 1), default=1.0, metavar="OAC",
                       help="how often gestures happen, 0..1 (default 1): below 1 the head holds still during "
                            "its weakest moments (about 1 - OAC of the time) and only that share of the brow "
                            "raises is kept")
    group.add_argument("--spatial", type=number_in(-1, 1), default=0.0, metavar="SPC",
                       help="amplitude about rest, -1..1 (default 0): the motion times 2^SPC")
    group.add_argument("--temporal", type=number_in(-1, 1), default=0.0, metavar="TMP",
                       help="duration of movements, -1..1 (default 0): above 0 longer and slower, below 0 "
                            "shorter and quicker; brow raises held longer or cut shorter")
    group.add_argument("--fluidity", type=number_in(-1, 1), default=0.0, metavar="FLD",
                       help="smoothness, -1..1 (default 0): above 0 the quick jerks are smoothed away, below 0 "
                            "they are boosted")
    group.add_argument("--power", type=number_in(-1, 1), default=0.0, metavar="PWR",
                       help="sharpness of accents, -1..1 (default 0): above 0 strong moments grow and weak ones "
                            "shrink (bursts and holds) and brow raises flick up, below 0 the motion evens out")
    group.add_argument("--repetition", type=number_in(0, 1), default=0.0, metavar="REP",
                       help="repeated nods (and a second brow raise) on strong accents, 0..1 (default 0)")
    group.add_argument("--still", action="store_true",
                       help="a head that keeps still but for an idle sway, and brows at rest (--activation 0)")


def expressivity(args: argparse.Namespace):
    """The Expressivity of the command line's controls, or None where they keep the motion as generated."""
    from ..errors import ConfigError
    from ..motion.expressivity import Expressivity

    controls = Expressivity(activation=args.activation, spatial=args.spatial, temporal=args.temporal,
                            fluidity=args.fluidity, power=args.power, repetition=args.repetition)
    if args.still:
        if args.activation != 1.0:
            raise ConfigError("--still is --activation 0: give one of them")
        controls = controls.with_changes(activation=0.0)
    return None if controls.is_neutral else controls


def add_face_options(parser: argparse.ArgumentParser) -> None:
    from ..motion.face.expressions import EXPRESSIONS
    from ..motion.face.lips import LIP_METHODS

    face = parser.add_argument_group(
        "lips and expressions", "The lips move with the speech in every condition alike: phones recognised by "
        "PocketSphinx become MPEG-4 visemes blended over time by dominance functions (--lips visemes, the "
        "default), an acoustic model maps the spectrum to the mouth's shape (--lips acoustic, any "
        "language), or both are averaged, the visemes' closures kept (--lips combined: held out by speaker it "
        "follows tracked mouths best). An expression is neutral unless asked.")
    face.add_argument("--lips", default="visemes", choices=[*LIP_METHODS, "none"],
                      help="how the lips move (default visemes; combined: visemes and acoustic together; none: no "
                           "lip FAPs)")
    face.add_argument("--transcript", default=None, metavar="TEXT|FILE",
                      help="what is said (the text, or a text file): its words are aligned to the audio for the "
                           "visemes; words the pronouncing dictionary lacks are left out, and a text that does "
                           "not fit the audio is ignored with a warning")
    face.add_argument("--language", default=None, metavar="CODE",
                      help="the transcript's language, an eSpeak NG code (es, de, fr, cmn, ...; 'prosody "
                           "languages' lists them): its phones come from eSpeak NG and are aligned to the "
                           "recording, in any language (default: English, aligned by PocketSphinx); needs pip install "
                           "'visual-prosody[languages]'")
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
                           "squeezed, eyes opened: Jia et al.'s partial expressions) and drives --model pad's "
                           "gestures (P, and A shifting each word's arousal); write --pad=-0.5,0.3,0 when it "
                           "starts with a minus")
    face.add_argument("--pad-map", default=None, metavar="FILE.json",
                      help="with --pad: a JSON file replacing the map from PAD to the partial expressions "
                           "(see docs/cli.md)")


def analysis_kwargs(args: argparse.Namespace, *, parallel: bool = True) -> dict:
    """The analysis settings of a command: its options and, with ``parallel``, every core this process may use
    (the features do not depend on how many processes analyse them; ``batch`` spreads its files instead)."""
    from audio_features.analysis import forked_workers

    chosen = {"fps": args.fps, "f0_floor_hz": args.f0_floor_hz, "f0_ceiling_hz": args.f0_ceiling_hz}
    if chosen["fps"] is None:  # not given: the library chooses by the output
        del chosen["fps"]
    return {**chosen, "workers": forked_workers()} if parallel else chosen


def finite_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if value != value or value in (float("inf"), float("-inf")):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


#: Options of the thesis's eyebrow rule and the EyebrowRule fields they set.
THESIS_BROW_OPTIONS = {"eyebrow_threshold": "threshold_hz", "eyebrow_semitones": "threshold_semitones",
                        "energy_threshold": "energy_threshold_db", "energy_relative": "energy_relative_db"}


def add_eyebrow_options(parser: argparse.ArgumentParser) -> None:
    from ..motion.eyebrows import AccentRule, EyebrowRule

    accent, thesis = AccentRule(), EyebrowRule()  # the defaults the help states are the rules' own
    group = parser.add_argument_group(
        "eyebrows", "The speech-driven brows rise on pitch accents judged against the speaker's own voice "
                    "(accent rule, the default), or follow the thesis's rule (--brows thesis): raise when the "
                    "pitch crosses 207 Hz, hold 300 ms and then while the energy stays at or above 45 dB.")
    group.add_argument("--brows", default="accent", choices=["accent", "thesis"],
                       help="eyebrow rule (default accent: raise where the voice, at speaking loudness, goes "
                            "--accent-semitones above the speaker's median pitch; for 0.3 to 1.2 s)")
    group.add_argument("--accent-semitones", type=finite_float, default=None, metavar="ST",
                       help="accent rule: semitones above the speaker's median pitch that raise the brows "
                            f"(default {accent.threshold_semitones:g}; lower raises more often)")
    group.add_argument("--eyebrow-threshold", type=positive_float, default=None, metavar="HZ",
                       help="thesis rule: a rising crossing of the conditioned pitch through HZ raises the brows "
                            f"(default {thesis.threshold_hz:g})")
    group.add_argument("--eyebrow-semitones", type=finite_float, default=None, metavar="ST",
                       help="thesis rule, speaker-relative threshold instead of --eyebrow-threshold: ST semitones "
                            "above the recording's median pitch (e.g. 4)")
    group.add_argument("--energy-threshold", type=finite_float, default=None, metavar="DB",
                       help=f"thesis rule: after {thesis.min_hold_s * 1000:g} ms the raise lasts while energy >= DB, "
                            f"in dB re 2e-5 Pa (default {thesis.energy_threshold_db:g})")
    group.add_argument("--energy-relative", type=finite_float, default=None, metavar="DB",
                       help="thesis rule, calibrated for recording level instead of --energy-threshold: the "
                            "recording's median voiced energy + DB (e.g. -25)")


def eyebrow_rule(args: argparse.Namespace):
    from ..errors import ConfigError
    from ..motion.eyebrows import AccentRule, EyebrowRule

    given = {name: getattr(args, name) for name in THESIS_BROW_OPTIONS if getattr(args, name) is not None}
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
    return EyebrowRule(**{THESIS_BROW_OPTIONS[name]: value for name, value in given.items()})


def motion_kwargs(args: argparse.Namespace) -> dict:
    """The keyword arguments of :func:`prosody.jobs.pipeline.convert` set by :func:`add_motion_options`."""
    face: dict = {}
    if hasattr(args, "live_lips"):
        face = {"live_lips": args.live_lips != "none", "expression": args.expression}
    if hasattr(args, "lips"):
        face = {"lips": None if args.lips == "none" else args.lips, "transcript": args.transcript,
                "expression": args.expression, "mouth_model": args.mouth_model, "pad": args.pad,
                "pad_map": args.pad_map, "language": args.language}
    return {"condition": args.condition, "ground_truth": getattr(args, "ground_truth", None), "model": args.model,
            "seed": args.seed, "eyebrow_rule": eyebrow_rule(args), **channel_kwargs(args), **face,
            "expressivity": expressivity(args),
            **analysis_kwargs(args)}


def making_options_given(args: argparse.Namespace) -> list[str]:
    """The flags of the options that make a stream from a recording (motion, analysis, brows) that ``args``
    sets to other than their defaults: a command given a stream to show, not a recording, would ignore them."""
    parser = argparse.ArgumentParser(add_help=False)
    add_motion_options(parser)
    add_analysis_options(parser)
    add_eyebrow_options(parser)
    given = []
    for action in parser._actions:  # argparse lists its options only there
        if action.option_strings and getattr(args, action.dest, action.default) != action.default:
            flag = max(action.option_strings, key=len)
            if flag not in given:
                given.append(flag)
    return given


def check_motion_options(args: argparse.Namespace) -> None:
    """Options that would make the output silently other than asked are refused."""
    from ..motion.conditions import check_condition

    # the library's rules, said with the command's flags (messages.said)
    check_condition(args.condition, ground_truth=getattr(args, "ground_truth", None),
                    model=getattr(args, "model", None), expressivity=expressivity(args))
    from ..motion.settings import ChannelSettings

    lips = getattr(args, "lips", getattr(args, "live_lips", "none"))
    ChannelSettings(disabled=channel_kwargs(args)["disabled"]).check_leaves_output(
        lips=lips != "none", face_layer=bool(getattr(args, "expression", None) or getattr(args, "pad", None)))
    if hasattr(args, "transcript"):  # the face's rules, before the audio is read
        from ..motion.settings import FaceSettings

        FaceSettings(lips=None if args.lips == "none" else args.lips, transcript=args.transcript,
                     language=args.language, mouth_model=args.mouth_model, pad=args.pad, pad_map=args.pad_map)
