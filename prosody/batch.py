"""Batch processing: every audio file of a folder tree converted and compared, in parallel.

Work goes through the standard :class:`concurrent.futures.Executor` interface: the file itself with one job,
local processes with ``jobs > 1``, or a Dask distributed cluster given its scheduler address (Dask's
``Client.get_executor()`` is such an executor). Each file's outputs go to their own folder, mirroring the
input tree; ``metrics.json`` is written last, so a folder holding it with the same settings is complete and
is skipped on a re-run (``force`` redoes it). A broken file is reported and skipped, never fatal.
"""

from __future__ import annotations

import json
import os
import sys
import time
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from audio_features import AUDIO_EXTENSIONS, AudioFeaturesError
from audio_features._atomic import atomic_write

from .conditions import CONDITION_ORDER, Condition
from .errors import ConfigError, ProsodyError
from .fap_table import PROSODY_FAPS

#: Ground-truth file endings looked up beside an audio file's stem, in order of preference.
GROUND_TRUTH_SUFFIXES = (".head.csv", ".fap")


@dataclass(frozen=True)
class BatchOptions:
    """Settings applied to every file (they are stored in each metrics.json to recognise complete outputs)."""

    conditions: tuple[str, ...] = tuple(c.value for c in CONDITION_ORDER)
    model: str | None = None
    seed: int = 0
    normalize: bool = False
    fps: float = 30.0
    f0_floor_hz: float = 75.0
    f0_ceiling_hz: float = 500.0
    plots: bool = False

    def __post_init__(self) -> None:
        parsed = tuple(Condition.parse(name).value for name in self.conditions)
        if not parsed:
            raise ConfigError("choose at least one condition")
        object.__setattr__(self, "conditions", parsed)


@dataclass
class FileOutcome:
    """What happened to one input file."""

    file: str
    status: str  # "done", "skipped" (already complete) or "failed"
    output: str
    ground_truth: str | None = None
    error: str | None = None
    seconds: float = 0.0
    metrics: dict | None = field(default=None, repr=False)


def find_audio_files(indir: str | os.PathLike[str]) -> list[Path]:
    """Audio files under ``indir`` (recursively, hidden folders skipped), as paths relative to it, sorted."""
    root = Path(indir)
    if not root.is_dir():
        raise ConfigError(f"{root}: not a folder")
    found = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith("."))
        for filename in filenames:
            if not filename.startswith(".") and Path(filename).suffix.lower() in AUDIO_EXTENSIONS:
                found.append(Path(dirpath, filename).relative_to(root))
    return sorted(found)


def find_ground_truth(relative: Path, directory: str | os.PathLike[str] | None) -> Path | None:
    """``<stem>.head.csv`` or ``<stem>.fap`` in ``directory`` at the audio's relative path, else at its top."""
    if directory is None:
        return None
    root = Path(directory)
    for folder in dict.fromkeys((root / relative.parent, root)):
        for suffix in GROUND_TRUTH_SUFFIXES:
            candidate = folder / (relative.stem + suffix)
            if candidate.is_file():
                return candidate
    return None


def output_folder(outdir: str | os.PathLike[str], relative: Path) -> Path:
    """Where one input's outputs go: ``OUTDIR/<relative folder>/<stem>/``."""
    return Path(outdir) / relative.parent / relative.stem


def _settings(options: BatchOptions, ground_truth: Path | None) -> dict:
    return {**asdict(options), "conditions": list(options.conditions),
            "ground_truth": str(ground_truth) if ground_truth else None}


def _complete(folder: Path, settings: dict) -> dict | None:
    """The stored metrics if ``folder`` holds a complete output made with the same settings."""
    try:
        metrics = json.loads((folder / "metrics.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return metrics if metrics.get("settings") == settings else None


def process_file(audio: str, relative: str, outdir: str, ground_truth: str | None, options: BatchOptions,
                 force: bool = False) -> FileOutcome:
    """Convert and compare one file; every failure is caught and returned, never raised.

    A top-level function, so process pools and Dask workers can run it.
    """
    from .compare import compare, write_comparison

    started = time.perf_counter()
    folder = output_folder(outdir, Path(relative))
    truth = Path(ground_truth) if ground_truth else None
    settings = _settings(options, truth)
    outcome = FileOutcome(relative, "done", str(folder), ground_truth)
    if not force:
        stored = _complete(folder, settings)
        if stored is not None:
            outcome.status, outcome.metrics = "skipped", stored
            return outcome
    conditions = [c for c in options.conditions if truth is not None or c != Condition.GROUND_TRUTH.value]
    try:
        if not conditions:
            raise ConfigError("only GROUND_TRUTH was asked for and no ground truth was found")
        comparison = compare(audio, ground_truth=truth, model=options.model, seed=options.seed,
                             normalize=options.normalize, conditions=conditions, fps=options.fps,
                             f0_floor_hz=options.f0_floor_hz, f0_ceiling_hz=options.f0_ceiling_hz)
        write_comparison(comparison, folder, plots=options.plots, report=options.plots,
                         extra={"settings": settings})
        outcome.metrics = comparison.metrics
    except (ProsodyError, AudioFeaturesError, OSError, ValueError) as error:
        outcome.status, outcome.error = "failed", _one_line(error)
    except Exception as error:  # noqa: BLE001 - one broken file must never stop the others
        outcome.status, outcome.error = "failed", f"unexpected {type(error).__name__}: {_one_line(error)}"
    outcome.seconds = time.perf_counter() - started
    return outcome


def _one_line(error: BaseException) -> str:
    if isinstance(error, OSError) and error.filename:
        return f"{error.filename}: {error.strerror or error}"
    return " ".join(str(error).split())


@contextmanager
def make_executor(*, jobs: int = 1, scheduler: str | None = None) -> Iterator[Executor | None]:
    """The executor for a batch: None (run in this process) for one local job, a process pool for more,
    or the ``concurrent.futures`` executor of a Dask distributed client connected to ``scheduler``."""
    if scheduler is not None:
        try:
            from distributed import Client
        except ImportError:
            raise ConfigError("--scheduler needs Dask distributed: pip install 'visual-prosody[cluster]'") from None
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError, ValueError) as error:
            raise ConfigError(f"cannot reach the Dask scheduler at {scheduler!r} ({error})") from None
        try:
            yield client.get_executor()
        finally:
            client.close()
    elif jobs > 1:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            yield pool
    else:
        yield None


class Progress:
    """A one-line progress bar on a terminal; silent when stderr is not one (pipes, CI)."""

    def __init__(self, total: int, *, stream=None, enabled: bool | None = None) -> None:
        self.total, self.done, self.stream = total, 0, stream or sys.stderr
        is_tty = getattr(self.stream, "isatty", lambda: False)()
        self.enabled = enabled if enabled is not None else bool(is_tty and not os.environ.get("CI"))

    def advance(self, outcome: FileOutcome) -> None:
        self.done += 1
        if self.enabled:
            width = 30
            filled = int(width * self.done / max(1, self.total))
            name = outcome.file if len(outcome.file) <= 40 else "..." + outcome.file[-37:]
            self.stream.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {self.done}/{self.total} {name:<40}")
            if self.done == self.total:
                self.stream.write("\n")
            self.stream.flush()


def run_batch(indir: str | os.PathLike[str], outdir: str | os.PathLike[str], *,
              ground_truth_dir: str | os.PathLike[str] | None = None, options: BatchOptions | None = None,
              jobs: int = 1, scheduler: str | None = None, force: bool = False,
              on_outcome: Callable[[FileOutcome], None] | None = None) -> dict:
    """Process every audio file under ``indir`` and write ``summary.json`` and ``summary.md`` to ``outdir``.

    Parameters
    ----------
    indir : path
        Folder searched recursively for audio files.
    outdir : path
        Output folder; each input gets ``OUTDIR/<relative folder>/<stem>/``.
    ground_truth_dir : path, optional
        Where ``<stem>.head.csv`` or ``<stem>.fap`` are looked up (same relative path, or the top).
    options : BatchOptions, optional
    jobs : int >= 1
        Local worker processes (ignored with ``scheduler``).
    scheduler : str, optional
        Address of a Dask distributed scheduler (e.g. ``tcp://10.0.0.5:8786``).
    force : bool
        Redo files whose outputs are already complete.
    on_outcome : callable, optional
        Called with each :class:`FileOutcome` as it finishes (progress display, logging).

    Returns
    -------
    dict
        The summary (also written as ``summary.json``): ``files``, ``counts``, ``aggregate``.
    """
    options = options or BatchOptions()
    if not (isinstance(jobs, int) and jobs >= 1):
        raise ConfigError(f"jobs must be a whole number >= 1, got {jobs!r}")
    if options.model is not None:
        from .head import ArxHeadModel

        ArxHeadModel.load(options.model)  # a bad model is one error up front, not one per file
        options = BatchOptions(**{**asdict(options), "model": str(Path(options.model).resolve())})
    files = find_audio_files(indir)
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    tasks = []
    for relative in files:
        truth = find_ground_truth(relative, ground_truth_dir)
        tasks.append((str(Path(indir) / relative), str(relative), str(out), str(truth) if truth else None))
    outcomes: dict[str, FileOutcome] = {}
    report = on_outcome or (lambda outcome: None)
    with make_executor(jobs=jobs, scheduler=scheduler) as executor:
        if executor is None:
            for task in tasks:
                outcome = process_file(*task, options, force)
                outcomes[outcome.file] = outcome
                report(outcome)
        else:
            futures: dict[Future, tuple] = {executor.submit(process_file, *task, options, force): task
                                            for task in tasks}
            for future in as_completed(futures):
                task = futures[future]
                try:
                    outcome = future.result()
                except Exception as error:  # noqa: BLE001 - a lost worker fails its file, not the batch
                    outcome = FileOutcome(task[1], "failed", str(output_folder(out, Path(task[1]))), task[3],
                                          error=f"worker failed: {type(error).__name__}: {_one_line(error)}")
                outcomes[outcome.file] = outcome
                report(outcome)
    ordered = [outcomes[str(relative)] for relative in files]
    summary = summarize(ordered, indir=str(indir), outdir=str(out))
    from .report import batch_markdown

    with atomic_write(out / "summary.json", newline="\n") as handle:
        json.dump(summary, handle, indent=1, allow_nan=False)
        handle.write("\n")
    with atomic_write(out / "summary.md", newline="\n") as handle:
        handle.write(batch_markdown(summary))
    return summary


def summarize(outcomes: Iterable[FileOutcome], *, indir: str, outdir: str) -> dict:
    """Counts, one entry per file, and per condition and FAP the mean Pearson r over files with truth."""
    outcomes = list(outcomes)
    entries = [{"file": o.file, "status": o.status, "output": o.output, "ground_truth": o.ground_truth,
                "error": o.error, "seconds": round(o.seconds, 3), "metrics": _compact(o.metrics)}
               for o in outcomes]
    with_truth = [o.metrics for o in outcomes if o.metrics is not None and o.ground_truth]
    aggregate: dict[str, dict] = {}
    for condition in CONDITION_ORDER:
        name = condition.value
        present = [m for m in with_truth if name in m["conditions"]]
        if not present:
            continue
        faps = {}
        for fap in PROSODY_FAPS:
            values = [m["conditions"][name][str(fap)]["pearson_r"] for m in present]
            values = [v for v in values if v is not None]
            faps[str(fap)] = {"pearson_r": float(np.mean(values)) if values else None, "files": len(values)}
        cca = [m["cca"]["head_vs_ground_truth"].get(name) for m in present]
        cca = [v for v in cca if v is not None]
        aggregate[name] = {"faps": faps, "cca_head_vs_ground_truth": float(np.mean(cca)) if cca else None}
    counts = {status: sum(o.status == status for o in outcomes) for status in ("done", "skipped", "failed")}
    counts["files"] = len(outcomes)
    counts["with_ground_truth"] = sum(o.ground_truth is not None for o in outcomes)
    return {"input": indir, "output": outdir, "counts": counts, "files": entries, "aggregate": aggregate}


def _compact(metrics: dict | None) -> dict | None:
    """The part of a file's metrics the summary keeps (statistics and CCA, not the settings)."""
    if metrics is None:
        return None
    return {key: metrics[key] for key in ("duration_s", "frames", "conditions", "cca",
                                                  "model_trained_on_this_recording") if key in metrics}
