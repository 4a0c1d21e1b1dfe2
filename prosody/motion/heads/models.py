"""Head models: what every one does (:class:`HeadModel`), and the models by name and by file.

Three kinds: the default prosodic generator, Zavala Chmelicka's ARX model and Jia et al.'s PAD gestures.
Model files are JSON and say what they hold in ``"format"``: ``visual-prosody-head`` for the prosodic
generator, ``visual-prosody-arx`` for the ARX model, ``visual-prosody-pad`` for the gestures
(:data:`MODEL_KINDS`). ``--model`` takes either a file or one of the names of :data:`SHIPPED_MODELS` and
:data:`NAMED_MODELS`.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, runtime_checkable

from ...errors import ModelError
from ...fap.table import HEAD_FAPS
from ..model_files import MODELS_DIR, read_model_json
from .arx import DEFAULT_MODEL_PATH as ARX_MODEL_PATH
from .arx import MODEL_FORMAT as ARX_FORMAT
from .arx import ArxHeadModel
from .pad import MODEL_FORMAT as PAD_FORMAT
from .pad import PadHeadModel
from .prosodic import MODEL_FORMAT as PROSODIC_FORMAT
from .prosodic import ProsodicHeadModel

if TYPE_CHECKING:
    import numpy as np

    from audio_features import Features


@runtime_checkable
class HeadModel(Protocol):
    """What every head model does: head motion from a recording's features, seeded, about a rest pose, and
    kept in a model file."""

    #: The model's name in reports and files (``prosodic``, ``arx``, ``pad``).
    kind: str
    #: Whether the motion depends on the seed (summaries then average over several seeds).
    stochastic: ClassVar[bool]
    #: The frame rate the model runs at (features at another rate are resampled to it and back).
    fps_: float

    def generate(self, features: Features, *, seed: int = 0) -> dict[int, np.ndarray]:
        """Head pitch, yaw and roll (FAP 48-50 -> curve, AU) on the features' grid."""
        ...

    def rest_pose_au(self) -> np.ndarray:
        """The pose the motion is about, AU (3,): gains scale the motion about it."""
        ...

    def to_dict(self) -> dict:
        """The model file's content."""
        ...


#: Model files by their ``"format"``: the class that reads each.
MODEL_KINDS: dict[str, Any] = {PROSODIC_FORMAT: ProsodicHeadModel, ARX_FORMAT: ArxHeadModel,
                               PAD_FORMAT: PadHeadModel}
#: Models made from their settings, by name: Jia et al.'s PAD-driven gestures and its random baseline.
NAMED_MODELS = {"pad": lambda: PadHeadModel(), "pad-random": lambda: PadHeadModel(randomized=True)}
PROSODIC_MODEL_PATH = MODELS_DIR / "default_head.json"
#: Shipped models by name: ``prosodic`` (the default) and ``arx`` (the thesis's model).
SHIPPED_MODELS = {"prosodic": PROSODIC_MODEL_PATH, "arx": ARX_MODEL_PATH}


def load_head_model(source: str | os.PathLike[str]) -> HeadModel:
    """A head model from a name (``prosodic``, ``arx``, ``pad``, ``pad-random``) or a model file of any kind.

    Raises
    ------
    ModelError
        The file is missing, unreadable, too large, not JSON, or not a model this release reads.
    """
    text_source = os.fspath(source)
    if isinstance(text_source, str) and text_source in NAMED_MODELS:
        return NAMED_MODELS[text_source]()
    if isinstance(text_source, str) and text_source in SHIPPED_MODELS:
        source = SHIPPED_MODELS[text_source]
    name = str(source)
    payload = read_model_json(source, shipped=(*SHIPPED_MODELS, *NAMED_MODELS))
    kind = payload.get("format") if isinstance(payload, dict) else None
    if isinstance(kind, str) and kind in MODEL_KINDS:
        return MODEL_KINDS[kind].from_dict(payload, source=name)
    raise ModelError(f"{name}: not a head model file (its \"format\" must be {PROSODIC_FORMAT!r}, "
                     f"{ARX_FORMAT!r} or {PAD_FORMAT!r})")


def default_head_model() -> ProsodicHeadModel:
    """The default speech-driven head shipped with the package (trained on the seven talking-head clips)."""
    model = load_head_model(PROSODIC_MODEL_PATH)
    assert isinstance(model, ProsodicHeadModel)
    return model


def resolve_head_model(model: HeadModel | str | os.PathLike[str] | None) -> HeadModel:
    """A model object from what a caller passed: None (the default), a name, a path or a model."""
    if model is None:
        return default_head_model()
    if isinstance(model, HeadModel):
        return model
    return load_head_model(model)


def rest_pose(model: HeadModel) -> dict[int, float]:
    """FAP -> AU of the pose the model rests in (0 for the prosodic generator and the gestures)."""
    pose = model.rest_pose_au()
    return {fap: float(pose[axis]) for axis, fap in enumerate(HEAD_FAPS)}


def is_stochastic(model: HeadModel) -> bool:
    """Whether the model's motion depends on the seed (summaries then average over several seeds)."""
    return bool(model.stochastic)
