"""The ``prosody`` command: the parser built from the commands' modules, and ``main``.

This is the only place that reads argv and decides exit codes: 0 ok, 1 processing error, 2 bad usage.
Heavy libraries are imported inside each command, so a command pays only for what it uses.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
from collections.abc import Callable, Sequence
from typing import Any

from . import messages as msg
from . import options as opt
from . import paths

#: The subcommands (each a module of this package), in the order --help lists them.
COMMAND_NAMES = ("features", "languages", "convert", "preview", "stream", "train", "compare", "batch", "track",
                 "study", "inspect")


class _Version(argparse.Action):
    """``--version``: the installed release, read only when asked for (reading it costs every command 35 ms)."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS, help=None) -> None:
        super().__init__(option_strings, dest, nargs=0, default=default, help=help)

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        import prosody

        print(f"prosody {prosody.__version__}")  # on standard output, as argparse's own version action
        parser.exit()


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The ``prosody`` command line: one subcommand per module of this package; ``only``: that command's
    alone (what a run of it needs: the others' modules are not imported)."""
    import importlib

    parser = opt.Parser(
        prog="prosody",
        description="Visual prosody from speech: head and eyebrow motion (MPEG-4 FAP streams) from audio.",
        epilog="Exit codes: 0 success, 1 processing error (bad input file, failed analysis), 2 usage error.",
    )
    parser.add_argument("--version", action=_Version, help="show the installed release and exit")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=opt.Parser)

    for name in COMMAND_NAMES if only is None else (only,):
        importlib.import_module(f"{__package__}.{name}").add_parser(commands)
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
            sub.set_defaults(parser=sub)  # its options name the library's parameters in messages (msg.said)
            _add_message_options(sub)


def _run(handler: Callable[[argparse.Namespace], int], args: argparse.Namespace) -> int:
    from ..errors import ParameterError, VisualProsodyError

    try:
        paths.check_paths(args)
        return handler(args)
    except ParameterError as error:  # prosody's ConfigError too
        msg.MESSAGES.emit("error", f"prosody {args.command}: error: {msg.said(error, args.parser)}",
                          exit=opt.EXIT_USAGE)
        return opt.EXIT_USAGE
    except VisualProsodyError as error:
        msg.MESSAGES.emit("error", f"prosody {args.command}: error: {msg.said(error, args.parser)}",
                          exit=opt.EXIT_FAILURE)
        return opt.EXIT_FAILURE
    except BrokenPipeError:
        raise  # the reader of our output went away: main() ends quietly
    except OSError as error:
        where = f"{error.filename}: " if error.filename else ""
        msg.MESSAGES.emit("error", f"prosody {args.command}: error: {where}{error.strerror or error}",
                       exit=opt.EXIT_FAILURE)
        return opt.EXIT_FAILURE


def interrupted(error: BaseException) -> bool:
    """Whether ``error`` is Ctrl-C: a KeyboardInterrupt, or an ImportError that a compiled module whose
    loading it stopped raised instead (``ImportError: KeyboardInterrupt``)."""
    seen: BaseException | None = error
    while seen is not None:
        if isinstance(seen, KeyboardInterrupt) or str(seen).strip().startswith("KeyboardInterrupt"):
            return True
        seen = seen.__cause__ or seen.__context__
    return False


def main(argv: Sequence[str] | None = None) -> int:
    """The ``prosody`` command. Called from Python (a test, a notebook), it leaves the process as it found it:
    the message mode, the SIGTERM handler and a closed standard error are restored when it returns. Ctrl-C at
    any point, an import's included, ends it with "interrupted" and exit code 130, never a traceback."""
    try:
        return _main(argv)
    except KeyboardInterrupt:
        msg.MESSAGES.emit("error", "prosody: interrupted", exit=130)
        msg.forget_interrupt()
        return 130
    except ImportError as error:
        if not interrupted(error):
            raise
        msg.MESSAGES.emit("error", "prosody: interrupted", exit=130)
        msg.forget_interrupt()
        return 130


def _main(argv: Sequence[str] | None) -> int:
    import signal
    import warnings

    arguments = sys.argv[1:] if argv is None else list(argv)
    # a run of one command builds that command's parser alone; help, --version and mistakes get them all
    named = arguments[0] if arguments and arguments[0] in COMMAND_NAMES else None
    parser = build_parser(named)
    args, unknown = parser.parse_known_args(arguments)
    if unknown:  # said by the command's own parser, which names the command and its --help
        getattr(args, "parser", parser).error(f"unrecognized arguments: {' '.join(unknown)}")
    mode = msg.MESSAGES.mode
    stderr = sys.stderr
    previous: Any = None
    try:
        if sys.stderr is None:  # started with standard error closed (2>&-): messages go nowhere, work goes on
            sys.stderr = open(os.devnull, "w")  # noqa: SIM115 - closed below
        msg.MESSAGES.mode = "json" if getattr(args, "messages", None) == "json" else (
            "quiet" if getattr(args, "quiet", False) else "text")

        def show(message, category, filename, lineno, file=None, line=None):
            # a warning is a note to the user, one line, not a source listing
            said = msg.said(message, getattr(args, "parser", None))
            msg.MESSAGES.emit("warning", f"prosody {args.command}: warning: {said}")

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
            msg.MESSAGES.emit("error", f"prosody {args.command}: interrupted", exit=130)
            msg.forget_interrupt()
            return 130
        except ImportError as error:
            if not interrupted(error):
                raise
            msg.MESSAGES.emit("error", f"prosody {args.command}: interrupted", exit=130)
            msg.forget_interrupt()
            return 130
        except BrokenPipeError:
            # the reader went away (`prosody inspect F.fap | head -1`): not an error of ours
            with contextlib.suppress(OSError):
                devnull = os.open(os.devnull, os.O_WRONLY)
                os.dup2(devnull, sys.stdout.fileno())
            return opt.EXIT_OK
    finally:
        if previous is not None:
            with contextlib.suppress(ValueError):
                signal.signal(signal.SIGTERM, previous)
        msg.MESSAGES.mode = mode
        if stderr is None and sys.stderr is not None:
            sys.stderr.close()
            sys.stderr = stderr
