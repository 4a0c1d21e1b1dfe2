"""Refit every shipped model from the shared data, the way each was made, and compare it with the shipped file.

Usage: python -m scripts.retrain_models [--only NAME[,NAME...]] [--write]   (``make models``)

Each model of ``prosody/motion/models/`` is refitted on ``../shared/data/talking-heads`` (or the folder
``PROSODY_SHARED_DATA`` names) into a temporary folder, by the command or function that made it:

- ``default_head.json``: ``prosody train --kind prosodic --cv`` (cross-validation chooses its settings);
- ``default_arx.json``: ``prosody train --kind arx --cv``;
- ``mouth_acoustic.json``: ``prosody train --kind mouth``;
- ``mouth_acoustic_videos.json`` (the default of ``--lips acoustic``): ``prosody train --kind mouth`` on the
  talking-heads clips and the talking videos, tracked first by ``prosody track`` into
  ``out/talking-videos-tracked`` (as ``experiments/mouth_videos_loso.py`` tracks them; about 20 minutes once);
- ``live_head_<MS>ms.json``: ``prosody train --kind live --lookahead-ms MS --cv`` (minutes each);
- ``live_mouth_<MS>ms.json``: :class:`prosody.motion.face.mouth_model.LiveMouthModel` fitted on every clip of the
  talking-heads clips and the tracked talking videos.

Each refit is compared with the shipped file number by number (relative 1e-9: the last digit follows the
machine's BLAS kernel; the training record's statistics are left out of the comparison). ``--write`` replaces
the shipped files with the refits.
"""

from __future__ import annotations

import json
import shutil
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from experiments.common import talking_heads

MODELS = Path(__file__).resolve().parents[1] / "prosody" / "motion" / "models"
#: Parts of a model file that record statistics of the fit rather than the model.
NOT_COMPARED = ("diagnostics", "cross_validation", "training")


def _train(*arguments: str) -> Callable[..., None]:
    def fit(data: Path, out: Path, extra: tuple[str, ...] = ()) -> None:
        from prosody.cli import main

        if main(["train", "--data", str(data), *extra, "-o", str(out), *arguments]) != 0:
            raise SystemExit(f"prosody train {' '.join(arguments)} failed")

    return fit


def _with_tracked_videos(fit: Callable[..., None]) -> Callable[[Path, Path], None]:
    """``fit`` given the talking-heads clips and the talking videos tracked into ``out/talking-videos-tracked``
    (tracked here where that folder does not hold them yet)."""
    def fit_both(data: Path, out: Path) -> None:
        from experiments.common import tracked_videos

        fit(data, out, extra=("--data", str(tracked_videos())))

    return fit_both


def _live_mouth(milliseconds: int) -> Callable[..., None]:
    def fit(data: Path, out: Path, extra: tuple[str, ...] = ()) -> None:
        from prosody.motion.face.mouth_model import LiveMouthModel, live_mouth_clips

        folders = [data, *(Path(folder) for flag, folder in zip(extra[::2], extra[1::2], strict=True)
                           if flag == "--data")]
        LiveMouthModel(milliseconds / 1000).fit([pair for folder in folders
                                                 for pair in live_mouth_clips(folder)]).save(out)

    return fit


def recipes() -> dict[str, Callable[[Path, Path], None]]:
    """Shipped file name -> how it is refitted."""
    from prosody.live.converter import SHIPPED_LOOKAHEADS_MS
    from prosody.motion.face.mouth_model import SHIPPED_LIVE_MOUTH_MS

    made = {"default_head.json": _train("--kind", "prosodic", "--cv"),
            "default_arx.json": _train("--kind", "arx", "--cv"),
            "mouth_acoustic.json": _train("--kind", "mouth"),
            "mouth_acoustic_videos.json": _with_tracked_videos(_train("--kind", "mouth"))}
    for ms in SHIPPED_LOOKAHEADS_MS:
        made[f"live_head_{ms}ms.json"] = _train("--kind", "live", "--lookahead-ms", str(ms), "--cv")
    for ms in SHIPPED_LIVE_MOUTH_MS:
        made[f"live_mouth_{ms}ms.json"] = _with_tracked_videos(_live_mouth(ms))
    return made


def differences(made: dict, shipped: dict, path: str = "") -> list[str]:
    """Where two model files disagree (numbers to relative 1e-9), as ``key: what`` lines."""
    found = []
    for key in sorted(set(made) | set(shipped)):
        where = f"{path}{key}"
        if not path and key in NOT_COMPARED:
            continue
        if key not in made or key not in shipped:
            found.append(f"{where}: only in the {'shipped file' if key in shipped else 'refit'}")
            continue
        a, b = made[key], shipped[key]
        if isinstance(a, dict) and isinstance(b, dict):
            found += differences(a, b, where + ".")
        elif isinstance(a, (int, float, list)) and not isinstance(a, bool) and _numeric(a) and _numeric(b):
            x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
            if x.shape != y.shape or not np.allclose(x, y, rtol=1e-9, atol=1e-12, equal_nan=True):
                found.append(f"{where}: numbers differ")
        elif a != b:
            found.append(f"{where}: {a!r} != {b!r}")
    return found


def _numeric(value: object) -> bool:
    try:
        np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return False
    return True


def main(argv: list[str]) -> int:
    write = "--write" in argv
    only = next((argv[i + 1] for i, a in enumerate(argv[:-1]) if a == "--only"), None)
    chosen = recipes()
    if only is not None:
        unknown = set(only.split(",")) - set(chosen)
        if unknown:
            raise SystemExit(f"--only: no shipped model {', '.join(sorted(unknown))}; choose from {', '.join(chosen)}")
        chosen = {name: fit for name, fit in chosen.items() if name in only.split(",")}
    data = talking_heads()
    failures = 0
    with tempfile.TemporaryDirectory() as folder:
        for name, fit in chosen.items():
            out = Path(folder) / name
            fit(data, out)
            found = differences(json.loads(out.read_text()), json.loads((MODELS / name).read_text()))
            failures += bool(found)
            print(f"{name}: {'the same as shipped' if not found else 'differs: ' + '; '.join(found[:5])}")
            if write:
                shutil.copyfile(out, MODELS / name)
    return 1 if failures and not write else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
