"""``python -m prosody`` and the ``prosody`` command (``pyproject.toml`` points it here).

The command's modules are imported inside :func:`main`, so that Ctrl-C while they load (the first few tenths
of a second) ends the command as it does later, with "interrupted" and exit code 130, not a traceback.
"""

import sys


def _interrupted() -> int:
    print("prosody: interrupted", file=sys.stderr)
    # CPython remembers an interrupt that stopped an import and would end the process by SIGINT at exit,
    # whatever the exit code; evaluating an empty statement at top level clears that record
    if sys.implementation.name == "cpython":
        try:
            import ctypes

            ctypes.pythonapi.PyRun_SimpleString(b"")
        except Exception:  # noqa: BLE001 - the exit code then stays as the interrupt left it
            pass
    return 130


def main() -> int:
    """Run the ``prosody`` command on ``sys.argv``; returns its exit code.

    Once the command has finished, Ctrl-C is ignored: the work is done and said, and an interrupt during the
    interpreter's own shutdown would otherwise end the process by SIGINT instead of the command's exit code."""
    heard: list[int] = []
    try:
        import signal

        def interrupt(signum, frame) -> None:
            heard.append(signum)
            raise KeyboardInterrupt

        # while the modules load, an interrupt is also remembered: a compiled module that Ctrl-C stopped may
        # report it as an ImportError of its own that does not name the interrupt (NumPy: "PyCapsule_Import
        # could not import module datetime")
        try:
            previous = signal.signal(signal.SIGINT, interrupt)
        except ValueError:  # not the main thread: no handler of its own
            previous = None
        try:
            from .cli.app import main as command
        finally:
            if previous is not None:
                signal.signal(signal.SIGINT, previous)
    except KeyboardInterrupt:
        return _interrupted()
    except ImportError as error:
        if not heard and "KeyboardInterrupt" not in f"{error!r} {error.__context__!r} {error.__cause__!r}":
            raise
        return _interrupted()
    try:
        code = command()
    finally:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    return code


if __name__ == "__main__":
    sys.exit(main())
