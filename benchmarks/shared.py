"""Where the benchmarks find the recordings they need: ``../shared/data`` beside the checkout, or the folder
``PROSODY_SHARED_DATA`` names (the same as the tests)."""

from __future__ import annotations

import os
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def shared_data() -> Path:
    return Path(os.environ.get("PROSODY_SHARED_DATA", REPO.parent / "shared" / "data"))


def talking_heads() -> Path:
    """The talking-heads clips (speech with tracked head, brows and mouths), or exit saying they are missing."""
    return data_folder("talking-heads", needs="the talking-heads clips (speech with tracked head, brows and mouths)")


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
    from prosody.motion.head_models import default_head_model
    from prosody.motion.speech_head import ProsodicHeadModel

    model = default_head_model()
    return {name: getattr(model, name) for name in ProsodicHeadModel.SETTINGS}
