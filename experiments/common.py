"""What the experiments (and benchmarks) share: where the recordings are (``../shared/data`` beside the
checkout, or the folder ``PROSODY_SHARED_DATA`` names, as for the tests), and the record of each experiment's
result in ``results/NAME.json``."""

from __future__ import annotations

import contextlib
import datetime
import hashlib
import io
import json
import os
import platform
import subprocess
import sys
from collections.abc import Callable, Iterable
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def shared_data() -> Path:
    return Path(os.environ.get("PROSODY_SHARED_DATA", REPO.parent / "shared" / "data"))


def talking_heads() -> Path:
    """The talking-heads clips (speech with tracked head, brows and mouths), or exit saying they are missing."""
    return data_folder("talking-heads", needs="the talking-heads clips (speech with tracked head, brows and mouths)")


TRACKED_VIDEOS = REPO / "out" / "talking-videos-tracked"


def tracked_videos() -> Path:
    """The clips of ``<shared data>/talking-videos`` tracked by ``prosody track`` into ``out/talking-videos-tracked``
    (complete outputs are kept and reused: about 20 minutes the first time, seconds after)."""
    from prosody.cli import main

    videos = data_folder("talking-videos", needs="the talking-videos clips")
    if main(["track", str(videos), "-o", str(TRACKED_VIDEOS), "-q", "--jobs", "2"]) != 0:
        raise SystemExit("prosody track failed on the talking videos")
    return TRACKED_VIDEOS


def data_folder(name: str, *, needs: str) -> Path:
    """``<shared data>/<name>``, or exit with one line saying what is missing and how to point at it."""
    folder = shared_data() / name
    if not folder.is_dir():
        raise SystemExit(f"{folder}: not found. This benchmark needs {needs}: the project's shared data folder "
                         "beside the checkout (../shared/data), or set PROSODY_SHARED_DATA=/path/to/data")
    return folder


def shipped_settings() -> dict:
    """The settings of the shipped default head (``prosody/motion/models/default_head.json``), which
    cross-validation chose: the benchmarks fit the prosodic generator with them."""
    from prosody.motion.heads.models import default_head_model
    from prosody.motion.heads.prosodic import ProsodicHeadModel

    model = default_head_model()
    return {name: getattr(model, name) for name in ProsodicHeadModel.SETTINGS}


RESULTS = REPO / "results"


@contextlib.contextmanager
def phone_loop_settings(**settings):
    """The phone loop (``audio_features.phones``) with ``settings`` over its shipped ones, put back after."""
    from audio_features import phones

    saved = dict(phones.PHONE_LOOP_SETTINGS)
    phones.PHONE_LOOP_SETTINGS.update(settings)
    try:
        yield
    finally:
        phones.PHONE_LOOP_SETTINGS.clear()
        phones.PHONE_LOOP_SETTINGS.update(saved)


def data_digest(paths: Iterable[Path]) -> str:
    """SHA-256 over every file under ``paths`` (relative name and content, in sorted order): which data a
    result was measured on, whatever its folders are called on another machine."""
    digest = hashlib.sha256()
    for root in sorted(Path(path) for path in paths if Path(path).exists()):
        files = sorted(p for p in root.rglob("*") if p.is_file()) if root.is_dir() else [root]
        for file in files:
            digest.update(str(file.relative_to(root if root.is_dir() else root.parent)).encode() + b"\0")
            with open(file, "rb") as handle:
                for block in iter(lambda: handle.read(1 << 20), b""):
                    digest.update(block)
    return digest.hexdigest()


def commit() -> tuple[str, bool]:
    """(the checkout's commit, whether its tracked files differ from it; the records of ``results/`` and the page
    rendered from them do not count, so that experiments run one after another are not marked by each other)."""
    def git(*args: str) -> str:
        return subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True, check=False).stdout.strip()

    changed = git("status", "--porcelain", "--untracked-files=no", "--", ".", ":(exclude)results",
                  ":(exclude)docs/results.md")
    return git("rev-parse", "HEAD") or "unknown", bool(changed)


def record(name: str, main: Callable[[], int | None], data: Callable[[], Iterable[Path]]) -> int:
    """Run an experiment's ``main``, show what it prints, and keep it in ``results/NAME.json``.

    The record holds the printed tables as they were, the commit they were measured at (and whether the
    checkout had changes), a digest of the data read, the time taken and the machine. An experiment that fails
    or exits early records nothing.
    """
    printed = io.StringIO()

    class Both(io.TextIOBase):
        def write(self, text: str) -> int:
            sys.__stdout__.write(text)
            return printed.write(text)

    started = datetime.datetime.now(datetime.timezone.utc)
    with contextlib.redirect_stdout(Both()):
        code = main() or 0
    if code:
        return code
    revision, dirty = commit()
    RESULTS.mkdir(exist_ok=True)
    entry = {"experiment": name, "commit": revision, "uncommitted_changes": dirty,
             "data_sha256": data_digest(data()), "started": started.isoformat(timespec="seconds"),
             "seconds": round((datetime.datetime.now(datetime.timezone.utc) - started).total_seconds(), 1),
             "machine": f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}",
             "report": printed.getvalue()}
    path = RESULTS / f"{name}.json"
    path.with_suffix(".tmp").write_text(json.dumps(entry, indent=1) + "\n")
    os.replace(path.with_suffix(".tmp"), path)
    return 0
