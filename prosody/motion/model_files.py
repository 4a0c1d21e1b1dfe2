"""What the head models' files share: the record of the recordings a model was trained on, and reading and
writing the JSON itself (plain data, never pickle; bounded in size and depth; errors name the file)."""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from audio_features.atomic import atomic_write
from audio_features.inputs import open_input, reading

from ..errors import ModelError

if TYPE_CHECKING:
    import numpy as np

#: Largest model file read (the shipped ones are well under 100 kB).
#: The folder of the shipped models (head and mouth models, JSON).
MODELS_DIR = Path(__file__).resolve().with_name("models")
MAX_MODEL_BYTES = 16 << 20
#: Largest magnitude of a number a model file may hold (the shipped models' largest is 1e4); beyond it the
#: arithmetic of generation overflows, so the file is damaged or hostile.
MAX_MODEL_MAGNITUDE = 1e9


@dataclass(frozen=True)
class TrainingClip:
    """A recording a model was trained on."""

    name: str
    frames: int
    duration_s: float
    #: SHA-256 of the audio file (None for audio that came from memory, or model files written before it).
    audio_sha256: str | None = None

    @classmethod
    def from_dict(cls, entry: dict) -> TrainingClip:
        """From a model file's ``training`` entry; KeyError, TypeError, ValueError or OverflowError if it is
        malformed (the model's reader turns them into a ModelError naming the file)."""
        if not isinstance(entry, dict):
            raise TypeError(f"a training entry must be an object, got {type(entry).__name__}")
        digest = entry.get("audio_sha256")
        if digest is not None and not isinstance(digest, str):
            raise TypeError("audio_sha256 must be a string")
        return cls(str(entry["name"]), int(entry["frames"]), float(entry["duration_s"]),
                   None if digest is None else str(digest))

    @classmethod
    def of(cls, name: str, frames: int, fps: float, source: str | None) -> TrainingClip:
        """A clip of ``frames`` at ``fps``, with the SHA-256 of its audio file ``source`` if it is one."""
        return cls(name, int(frames), frames / fps, audio_digest(source))


def audio_digest(path: str | os.PathLike[str] | None) -> str | None:
    """SHA-256 of an audio file, or None when ``path`` is None or not a readable regular file."""
    from audio_features.inputs import file_sha256

    if path is None:
        return None
    try:
        return file_sha256(path)
    except OSError:
        return None


def write_model_json(payload: dict, path: str | os.PathLike[str], *, extra: dict | None = None) -> None:
    """Write a model's data (and ``extra`` fields, such as cross-validation figures) as JSON, atomically."""
    if extra:
        payload = {**payload, **extra}
    with atomic_write(path) as handle:
        json.dump(payload, handle, indent=1, allow_nan=False)
        handle.write("\n")


def read_model_json(path: str | os.PathLike[str], *, shipped: tuple[str, ...] = ()) -> object:
    """The JSON data of a model file, read within :data:`MAX_MODEL_BYTES`.

    Raises
    ------
    ModelError
        The file is missing (the message lists the ``shipped`` model names), unreadable, too large, not
        text, not JSON, or nested too deeply.
    """
    name = str(path)
    try:
        with reading(name, ModelError, wanted="model file"), open_input(Path(path)) as handle:
            data = handle.read(MAX_MODEL_BYTES + 1)
    except ModelError as error:
        if not str(error).endswith(": no such file"):
            raise
        also = f" (or give a shipped model: {', '.join(shipped)})" if shipped else ""
        raise ModelError(f"{name}: no such model file{also}") from None
    if len(data) > MAX_MODEL_BYTES:
        raise ModelError(f"{name}: larger than {MAX_MODEL_BYTES >> 20} MiB; not a model file")
    try:
        return json.loads(data.decode("utf-8-sig"))  # a byte-order mark, as some editors write, is no error
    except UnicodeDecodeError:
        raise ModelError(f"{name}: not a text (JSON) model file") from None
    except json.JSONDecodeError as error:
        raise ModelError(f"{name}: not JSON (line {error.lineno}: {error.msg})") from None
    except RecursionError:
        raise ModelError(f"{name}: JSON nested too deeply to be a model file") from None


def model_payload(payload: object, *, format_name: str, source: str, version: int | None = None) -> dict:
    """``payload`` (a model file's data) if its ``"format"`` is ``format_name`` and, when given, its ``"version"``
    is ``version``; else :class:`ModelError` naming ``source``. Each reader then checks its own fields.

    Parameters
    ----------
    payload : object
        What the file held.
    format_name : str
        The format the reader reads.
    source : str
        The file, as messages name it.
    version : int, optional
        The version this release reads.

    Returns
    -------
    dict
    """
    if not isinstance(payload, dict) or payload.get("format") != format_name:
        raise ModelError(f"{source}: not a {format_name} model file (no \"format\": \"{format_name}\")")
    if version is not None and payload.get("version") != version:
        raise ModelError(f"{source}: model version {payload.get('version')!r} is not supported (this release "
                         f"reads version {version})")
    return payload


def model_array(payload: dict, key: str, shape: tuple[int, ...], fail: Callable[[str], ModelError]) -> np.ndarray:
    """The array field ``key`` of a model file's data, checked: of ``shape``, finite, and within
    :data:`MAX_MODEL_MAGNITUDE` (beyond it the file is damaged or hostile); else ``fail(problem)`` is raised.

    Parameters
    ----------
    payload : dict
        The file's data.
    key : str
    shape : tuple of int
    fail : callable
        Makes the :class:`ModelError` naming the file from the problem.

    Returns
    -------
    numpy.ndarray
    """
    import math

    import numpy as np

    array = np.array(payload[key], dtype=float)
    if array.size == 0 and math.prod(shape) == 0:
        array = array.reshape(shape)
    if array.shape != shape:
        raise fail(f"field {key!r} has shape {array.shape!r}, expected {shape!r}")
    if not np.all(np.isfinite(array)):
        raise fail(f"field {key!r} holds non-finite numbers")
    if np.any(np.abs(array) > MAX_MODEL_MAGNITUDE):
        raise fail(f"field {key!r} holds numbers beyond {MAX_MODEL_MAGNITUDE:g}: not a fitted model")
    return array


Model = TypeVar("Model", bound="JsonModel")


class JsonModel:
    """A model kept as one JSON file: the one way every model of the package is written and read.

    A model class gives :meth:`to_dict` (its data, with ``"format"`` and ``"version"``) and :meth:`from_dict`
    (checking them with :func:`model_payload`, then its own fields, raising :class:`ModelError` naming
    ``source``); :meth:`save` and :meth:`load` are these.
    """

    def to_dict(self) -> dict:
        """The model's data as plain JSON values."""
        raise NotImplementedError

    @classmethod
    def from_dict(cls: type[Model], payload: object, *, source: str = "<dict>") -> Model:
        """The model from :meth:`to_dict`'s data; :class:`ModelError` naming ``source`` if it is not one."""
        raise NotImplementedError

    def save(self, path: str | os.PathLike[str], *, extra: dict[str, Any] | None = None) -> None:
        """Write the model as JSON (plain data, never pickle), atomically, with ``extra`` fields such as
        held-out figures.

        Parameters
        ----------
        path : path-like
        extra : dict, optional
        """
        write_model_json(self.to_dict(), path, extra=extra)

    @classmethod
    def load(cls: type[Model], path: str | os.PathLike[str]) -> Model:
        """Read a model file written by :meth:`save`; :class:`ModelError` names the file and the problem.

        Parameters
        ----------
        path : path-like

        Returns
        -------
        the model
        """
        return cls.from_dict(read_model_json(path), source=str(path))
