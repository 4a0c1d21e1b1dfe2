"""``prosody features``: F0, conditioned F0 and energy per frame, as CSV."""

from __future__ import annotations

import argparse

from . import messages as msg
from . import options as opt


def run(args: argparse.Namespace) -> int:
    from audio_features import extract_features

    from ..errors import ConfigError

    if args.output != "-" and not args.output.lower().endswith(".csv"):
        raise ConfigError(f"-o {args.output!r}: features are written as CSV; name the file .csv (or - for "
                          "standard output)")
    if args.output == "-":
        features = extract_features(args.input, **opt.analysis_kwargs(args))
        msg.to_stdout(features.write_csv, "features.csv")
        return opt.EXIT_OK

    features = extract_features(args.input, **opt.analysis_kwargs(args))
    features.write_csv(args.output)
    msg.say(f"{args.output}: {features.n_frames} frames at {features.fps:g} fps "
            f"({features.duration_s:.2f} s, {int(features.f0.voiced.sum())} voiced)")
    return opt.EXIT_OK


def add_parser(commands) -> None:
    """Add the command to the subcommands of ``prosody``."""
    features = commands.add_parser(
        "features", help="write F0, conditioned F0 and energy per frame to CSV",
        description="Extract Praat F0 (empty where unvoiced), the spline-conditioned F0 and Praat intensity "
                    "(dB re 2e-5 Pa) on the frame grid, one CSV row per frame: "
                    "frame,time_s,f0_hz,f0_conditioned_hz,energy_db.",
    )
    features.add_argument("input", help="audio file (WAV, FLAC, OGG, MP3, ...; mixed to mono)")
    features.add_argument("-o", "--output", required=True, help="CSV file to write (.csv), or - for standard output")
    opt.add_analysis_options(features)
    features.set_defaults(handler=run)
