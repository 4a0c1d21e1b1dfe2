"""``prosody inspect``: describe a .fap file, or print it as JSON."""

from __future__ import annotations

import argparse
import json
import sys

from . import options as opt


def run(args: argparse.Namespace) -> int:
    from ..fap.fapfile import read_fap
    from ..fap.inspect import inspect_json, inspect_summary

    fap = read_fap(args.input, strict=args.strict)  # irregularities arrive as warnings, one line each
    if args.json:
        json.dump(inspect_json(fap), sys.stdout)
        sys.stdout.write("\n")
    else:
        print(inspect_summary(fap))
    return opt.EXIT_OK


def add_parser(commands) -> None:
    """Add the command to the subcommands of ``prosody``."""
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
    inspect.set_defaults(handler=run)
