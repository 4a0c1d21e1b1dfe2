"""``prosody languages``: the transcript languages of ``--language``."""

from __future__ import annotations

import argparse

from . import options as opt


def run(args: argparse.Namespace) -> int:
    from audio_features.espeak import languages

    for code, voice in languages().items():
        print(f"{code}\t{voice}")
    return opt.EXIT_OK


def add_parser(commands) -> None:
    """Add the command to the subcommands of ``prosody``."""
    languages = commands.add_parser(
        "languages", help="list the transcript languages of --language (eSpeak NG's codes)",
        description="Print the language codes --language takes with a transcript, one per line with the name of "
                    "an eSpeak NG voice that speaks it: the transcript's phones come from eSpeak NG and are "
                    "aligned to the recording, so the lips articulate in any of them. Needs pip install "
                    "'visual-prosody[languages]'.")
    languages.set_defaults(handler=run)
