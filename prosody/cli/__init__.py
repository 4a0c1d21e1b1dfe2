"""The ``prosody`` command line: one module per command, each with ``add_parser(commands)`` and ``run(args)``.

:func:`main` (in :mod:`prosody.cli.app`) reads argv and returns the exit code; the commands only turn flags
into the library's calls and say what happened.
"""

from .app import build_parser, main

__all__ = ["build_parser", "main"]
