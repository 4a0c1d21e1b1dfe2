"""The ``prosody`` command: a thin shell over the package's functions.

This is the only module that reads argv and decides exit codes: 0 ok, 1 processing error, 2 bad usage.
Heavy libraries are imported inside each command, so a command pays only for what it uses.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

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


def _add_analysis_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--fps", type=_positive_float, default=30.0,
                        help="frames per second of the output grid (default 30; frame k is at k/fps s)")
    parser.add_argument("--f0-floor", type=_positive_float, default=75.0, metavar="HZ",
                        help="lowest F0 the pitch tracker looks for, in Hz (default 75)")
    parser.add_argument("--f0-ceiling", type=_positive_float, default=500.0, metavar="HZ",
                        help="highest F0 the pitch tracker looks for, in Hz (default 500)")


def _analysis_kwargs(args: argparse.Namespace) -> dict:
    return {"fps": args.fps, "f0_floor_hz": args.f0_floor, "f0_ceiling_hz": args.f0_ceiling}


# commands -----------------------------------------------------------------------------------------------
def _cmd_features(args: argparse.Namespace) -> int:
    from audio_features import extract_features

    features = extract_features(args.input, **_analysis_kwargs(args))
    features.write_csv(args.output)
    print(f"{args.output}: {features.n_frames} frames at {features.fps:g} fps "
          f"({features.duration_s:.2f} s, {int(features.f0.voiced.sum())} voiced)", file=sys.stderr)
    return EXIT_OK


def _cmd_inspect(args: argparse.Namespace) -> int:
    from .fapfile import read_fap
    from .inspect import inspect_json, inspect_summary

    fap = read_fap(args.input)
    for warning in fap.warnings:
        print(f"{args.input}: warning: {warning}", file=sys.stderr)
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
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_Parser)

    features = commands.add_parser(
        "features", help="write F0, conditioned F0 and energy per frame to CSV",
        description="Extract Praat F0 (empty where unvoiced), the spline-conditioned F0 and Praat intensity "
                    "(dB re 2e-5 Pa) on the frame grid, one CSV row per frame: "
                    "frame,time_s,f0_hz,f0_conditioned_hz,energy_db.",
    )
    features.add_argument("input", help="audio file (WAV, FLAC, OGG, MP3, ...; mixed to mono)")
    features.add_argument("-o", "--output", required=True, help="CSV file to write")
    _add_analysis_options(features)
    features.set_defaults(handler=_cmd_features)

    inspect = commands.add_parser(
        "inspect", help="describe a .fap file (or print it as JSON)",
        description="Read a .fap file liberally and describe it; irregularities are reported on stderr.",
    )
    inspect.add_argument("input", help=".fap file")
    inspect.add_argument("--json", action="store_true",
                         help='print {"version", "name", "fps", "frames", "faps": {"<n>": [value or null, ...]}}')
    inspect.set_defaults(handler=_cmd_inspect)
    return parser


def _run(handler: Callable[[argparse.Namespace], int], args: argparse.Namespace) -> int:
    from audio_features import AudioFeaturesError
    from audio_features import ParameterError as AudioParameterError

    from .errors import ConfigError, ProsodyError

    try:
        return handler(args)
    except (ConfigError, AudioParameterError) as error:
        print(f"prosody {args.command}: error: {error}", file=sys.stderr)
        return EXIT_USAGE
    except (ProsodyError, AudioFeaturesError) as error:
        print(f"prosody {args.command}: error: {error}", file=sys.stderr)
        return EXIT_FAILURE
    except OSError as error:
        where = f"{error.filename}: " if error.filename else ""
        print(f"prosody {args.command}: error: {where}{error.strerror or error}", file=sys.stderr)
        return EXIT_FAILURE


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return _run(args.handler, args)
    except KeyboardInterrupt:
        print(f"prosody {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
