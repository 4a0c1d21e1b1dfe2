"""The one way batch jobs run their tasks (``prosody batch``'s recordings, ``prosody track``'s videos): in this
process, in a pool of local processes, or on a Dask cluster through its ``concurrent.futures`` executor.

:func:`run_tasks` yields each task's outcome as it finishes. A task that raises, a worker that dies and a
cluster left without workers each become that task's failed outcome (one line, made by the caller's
``failed``), never an exception: one broken input never stops the others. After a worker process dies, every
task it left undone runs again alone in a fresh process, so that only the task that kills its process fails.

Examples
--------
>>> list(run_tasks(abs, [(-2,), (3,)], failed=lambda task, why: None))
[((-2,), 2), ((3,), 3)]
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import CancelledError, Executor, Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from typing import TypeVar

from ..errors import ConfigError

__all__ = ["NO_WORKER_TIMEOUT_S", "SCHEDULER_TIMEOUT_S", "completed_futures", "make_executor", "one_line",
           "run_tasks"]

Outcome = TypeVar("Outcome")


def one_line(error: BaseException) -> str:
    """An error as one line: its file and the system's reason for an OSError, else its message's words."""
    if isinstance(error, OSError) and error.filename:
        return f"{error.filename}: {error.strerror or error}"
    return " ".join(str(error).split())


class _NoWorkers(Exception):
    """Every worker of the cluster is gone."""


#: Seconds without a single Dask worker after which the files still queued are failed.
NO_WORKER_TIMEOUT_S = 60.0


def completed_futures(futures: dict[Future, tuple], *, alive: Callable[[], bool] | None = None,
               poll_s: float = 2.0) -> Iterator[tuple[tuple, object]]:
    """``(task, outcome or exception)`` as the futures finish. With ``alive`` (the cluster still has
    workers), waiting stops when it has had none for :data:`NO_WORKER_TIMEOUT_S`: the rest are failed."""
    from concurrent.futures import FIRST_COMPLETED, wait

    pending = set(futures)
    without_workers_since: float | None = None
    while pending:
        done, pending = wait(pending, timeout=poll_s, return_when=FIRST_COMPLETED)
        for future in done:
            try:
                yield futures[future], future.result()
            except BaseException as error:  # noqa: BLE001 - reported per file
                if isinstance(error, (KeyboardInterrupt, SystemExit)):
                    raise
                yield futures[future], error
        if done or alive is None:
            without_workers_since = None
            continue
        if alive():
            without_workers_since = None
        elif without_workers_since is None:
            without_workers_since = time.monotonic()
        elif time.monotonic() - without_workers_since > NO_WORKER_TIMEOUT_S:
            for future in pending:
                future.cancel()
                yield futures[future], _NoWorkers(
                    f"the Dask cluster has had no worker for {NO_WORKER_TIMEOUT_S:.0f} s; this file was not done")
            return


#: Longest wait for a Dask scheduler to answer, in s.
SCHEDULER_TIMEOUT_S = 20.0
#: Time beyond it given to Dask to report its own timeout, in s.
_SCHEDULER_GRACE_S = 5.0


def _connect(client_class, scheduler: str):
    """A Dask client of ``scheduler``, or ConfigError within :data:`SCHEDULER_TIMEOUT_S` (Dask's own timeout
    covers the connection, not a listener that accepts and never answers, so the wait is bounded here)."""
    import threading

    outcome: list = []

    def connect() -> None:
        try:
            outcome.append(client_class(scheduler, timeout=f"{SCHEDULER_TIMEOUT_S:g}s"))
        except BaseException as error:  # noqa: BLE001 - handed to the waiting thread
            outcome.append(error)

    thread = threading.Thread(target=connect, name="dask-connect", daemon=True)
    thread.start()
    thread.join(SCHEDULER_TIMEOUT_S + _SCHEDULER_GRACE_S)
    if not outcome:
        raise ConfigError(f"the Dask scheduler at {scheduler!r} did not answer within {SCHEDULER_TIMEOUT_S:g} s "
                          "(is it a Dask scheduler?)")
    if isinstance(outcome[0], (OSError, TimeoutError, ValueError)):
        raise ConfigError(f"cannot reach the Dask scheduler at {scheduler!r} ({outcome[0]})") from None
    if isinstance(outcome[0], BaseException):
        raise outcome[0]
    return outcome[0]


@contextmanager
def make_executor(*, jobs: int = 1, scheduler: str | None = None) -> Iterator[Executor | None]:
    """The executor for a batch: None (run in this process) for one local job, a process pool for more,
    or the ``concurrent.futures`` executor of a Dask distributed client connected to ``scheduler``."""
    if scheduler is not None:
        try:
            from distributed import Client
        except ImportError:
            raise ConfigError("scheduler= needs Dask distributed: pip install 'visual-prosody[cluster]'",
                              parameter="scheduler") from None
        client = _connect(Client, scheduler)
        executor = client.get_executor()

        def workers_alive() -> bool:
            try:
                return bool(client.scheduler_info().get("workers"))
            except Exception:  # noqa: BLE001 - a lost scheduler has no workers for us either
                return False

        executor.workers_alive = workers_alive
        try:
            yield executor
        finally:
            with contextlib.suppress(Exception):
                client.close()
    elif jobs > 1:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            yield pool
    else:
        yield None


def run_tasks(function: Callable[..., Outcome], tasks: Iterable[tuple], *, failed: Callable[[tuple, str], Outcome],
              jobs: int = 1, scheduler: str | None = None) -> Iterator[tuple[tuple, Outcome]]:
    """``(task, function(*task))`` for every task, as each finishes.

    Parameters
    ----------
    function : callable
        Runs one task (its arguments are the task's items) and returns its outcome; in a worker process it must
        be importable (a module's function) and its arguments picklable.
    tasks : iterable of tuple
    failed : callable (task, why) -> outcome
        The outcome of a task that could not run: a worker that raised, died or was lost with its cluster.
    jobs : int
        Local worker processes (1: in this process; ignored with ``scheduler``).
    scheduler : str, optional
        The address of a Dask distributed scheduler.

    Yields
    ------
    (tuple, outcome)
    """
    tasks = list(tasks)
    with make_executor(jobs=jobs, scheduler=scheduler) as executor:
        if executor is None:
            for task in tasks:
                yield task, function(*task)
            return
        futures: dict[Future, tuple] = {executor.submit(function, *task): task for task in tasks}
        broken: list[tuple] = []
        for task, result in completed_futures(futures, alive=getattr(executor, "workers_alive", None)):
            if isinstance(result, BrokenProcessPool):
                broken.append(task)  # a worker died: which task killed it is found below
            elif isinstance(result, CancelledError):
                yield task, failed(task, "the Dask scheduler was lost before this was done")
            elif isinstance(result, _NoWorkers):
                yield task, failed(task, str(result))
            elif isinstance(result, BaseException):
                yield task, failed(task, f"worker failed: {type(result).__name__}: {one_line(result)}")
            else:
                yield task, result  # type: ignore[misc]
    for task in broken:  # each left undone runs alone in a fresh process: only the one that kills it fails
        yield task, _alone(function, task, failed)


def _alone(function: Callable[..., Outcome], task: tuple, failed: Callable[[tuple, str], Outcome]) -> Outcome:
    with ProcessPoolExecutor(max_workers=1) as alone:
        try:
            return alone.submit(function, *task).result()
        except BrokenProcessPool:
            return failed(task, "the worker process died while processing this (out of memory, or a crash in "
                                "native code)")
        except Exception as error:  # noqa: BLE001 - reported as the task's failure
            return failed(task, f"worker failed: {type(error).__name__}: {one_line(error)}")
