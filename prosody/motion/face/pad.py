"""An emotional state in PAD (pleasure, arousal, dominance) for a recording, and what it does to the face.

PAD is given for the whole recording (``"P,A,D"``, each -1..1) or timed, as a CSV file with the columns
``start_s,end_s,pleasure,arousal,dominance``. Jia et al.'s questionnaire (Eq. 13) gives PAD from twelve answers:
:func:`prosody.motion.heads.pad.pad_from_questionnaire`.

Two things follow from it:

- the head of Jia et al.'s gestures (``--model pad``): each prosodic word takes the pleasure P of the moment it
  peaks in, and the state's arousal shifts the word's own A (quantised from its prominence) by ``A / 2``,
  clipped to 0..1; pauses keep A = -0.5 (Jia et al.'s silence);
- the face, through Jia et al.'s partial expression parameters: raise the eyebrows, squeeze them, open the eyes.
  Jia et al. (2013) fits them to PAD with weights it does not publish; this project uses a linear map of its own
  (:data:`DEFAULT_FACE_MAP`: each parameter is ``wP * P + wA * A + wD * D``, then each parameter moves its FAPs
  by the amounts given at 1), in a JSON file a user can replace (``--pad-map``). Its directions follow the
  expressions PAD places at its corners: aroused and submissive states (fear, surprise: A+, D-) raise the
  brows; displeased, aroused and dominant ones (anger: P-, A+, D+) squeeze them; arousal opens the eyes.
  Timed states are blended over time as expressions are (see :mod:`prosody.motion.face.expressions`).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ...errors import ConfigError
from .expressions import blend_targets, read_timed_rows

#: Columns of a timed PAD file.
PAD_FILE_COLUMNS = ("start_s", "end_s", "pleasure", "arousal", "dominance")
FACE_MAP_FORMAT = "visual-prosody-pad-face"
#: Jia et al.'s partial expression parameters: PAD weights (P, A, D) and the FAPs each moves at 1 (FAP units).
DEFAULT_FACE_MAP: dict[str, dict] = {
    "brow_raise": {"weights": [0.0, 0.6, -0.4], "faps": {31: 100, 32: 100, 33: 80, 34: 80, 35: 60, 36: 60}},
    "brow_squeeze": {"weights": [-0.5, 0.3, 0.4], "faps": {37: 80, 38: 80, 31: -40, 32: -40}},
    # FAP 19-22 close the eyelids when positive: opening the eyes lowers them
    "eye_opening": {"weights": [0.1, 0.7, 0.0], "faps": {19: -120, 20: -120, 21: -40, 22: -40}},
}


@dataclass(frozen=True)
class PadSegment:
    """A PAD state from ``start_s`` to ``end_s`` (None: to the end); each of P, A, D in [-1, 1]."""

    pleasure: float
    arousal: float
    dominance: float
    start_s: float = 0.0
    end_s: float | None = None

    def __post_init__(self) -> None:
        for name in ("pleasure", "arousal", "dominance"):
            value = getattr(self, name)
            if isinstance(value, bool) or not (isinstance(value, (int, float)) and -1 <= value <= 1):
                raise ConfigError(f"{name} must be a number in [-1, 1], got {value!r}", parameter=name)
        end = math.inf if self.end_s is None else self.end_s
        if not (math.isfinite(self.start_s) and 0 <= self.start_s < end):
            raise ConfigError(f"a PAD state needs 0 <= start_s < end_s, got {self.start_s!r} and {self.end_s!r}",
                              parameter="start_s")

    def covers(self, time_s: float) -> bool:
        return self.start_s <= time_s < (math.inf if self.end_s is None else self.end_s)


def parse_pad(spec: str) -> list[PadSegment]:
    """``P,A,D`` for the whole recording, or the path of a CSV file of timed states (:data:`PAD_FILE_COLUMNS`).

    Examples
    --------
    >>> parse_pad("0.5,-0.2,0")
    [PadSegment(pleasure=0.5, arousal=-0.2, dominance=0.0, start_s=0.0, end_s=None)]
    """
    if os.path.exists(spec) or spec.lower().endswith(".csv"):
        return read_pad_file(spec)
    parts = spec.split(",")
    try:
        values = [float(part) for part in parts]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise ConfigError(f"PAD {spec!r}: expected P,A,D (three numbers from -1 to 1, e.g. 0.5,0.3,0) or a CSV file")
    return [PadSegment(*values)]


def read_pad_file(path: str | os.PathLike[str]) -> list[PadSegment]:
    """Timed PAD states from a CSV file (columns :data:`PAD_FILE_COLUMNS`)."""
    segments = []
    for line, row in read_timed_rows(path, PAD_FILE_COLUMNS, what="PAD"):
        try:
            start, end, pleasure, arousal, dominance = (float(cell) for cell in row)
            segments.append(PadSegment(pleasure, arousal, dominance, start, end))
        except (ValueError, ConfigError) as error:
            raise ConfigError(f"{path}, line {line}: expected {','.join(PAD_FILE_COLUMNS)} ({error})") from None
    return segments


def pad_at(segments: Sequence[PadSegment], time_s: float) -> tuple[float, float, float]:
    """(P, A, D) at a moment: the last state that covers it, neutral (0, 0, 0) where none does."""
    for segment in reversed(segments):
        if segment.covers(time_s):
            return segment.pleasure, segment.arousal, segment.dominance
    return 0.0, 0.0, 0.0


def read_face_map(path: str | os.PathLike[str] | None) -> dict[str, dict]:
    """The PAD -> partial expression map: :data:`DEFAULT_FACE_MAP`, or a JSON file of the same shape
    (``{"format": "visual-prosody-pad-face", "parameters": {name: {"weights": [wP, wA, wD], "faps": {FAP:
    value}}}}``), checked."""
    if path is None:
        return DEFAULT_FACE_MAP
    from audio_features.inputs import open_input

    name = str(path)
    try:
        with open_input(path, text=True, encoding="utf-8-sig", max_bytes=1 << 20) as handle:
            payload = json.load(handle)
    except FileNotFoundError:
        raise ConfigError(f"{name}: no such PAD map file") from None
    except (OSError, UnicodeDecodeError, ValueError) as error:
        raise ConfigError(f"{name}: not a JSON file ({getattr(error, 'strerror', None) or error})") from None
    if not isinstance(payload, dict) or payload.get("format") != FACE_MAP_FORMAT:
        raise ConfigError(f"{name}: not a PAD map (no \"format\": \"{FACE_MAP_FORMAT}\")")
    parameters = payload.get("parameters")
    if not isinstance(parameters, dict) or not parameters:
        raise ConfigError(f"{name}: \"parameters\" must name at least one partial expression parameter")
    checked: dict[str, dict] = {}
    for key, entry in parameters.items():
        try:
            weights = [float(w) for w in entry["weights"]]
            faps = {int(fap): float(value) for fap, value in entry["faps"].items()}
        except (KeyError, TypeError, ValueError, AttributeError):
            raise ConfigError(f"{name}: parameter {key!r} needs \"weights\" [wP, wA, wD] and \"faps\" "
                              "{FAP: value}") from None
        if len(weights) != 3 or not all(math.isfinite(w) and abs(w) <= 10 for w in weights):
            raise ConfigError(f"{name}: parameter {key!r}: \"weights\" must be three numbers within +-10")
        if not all(3 <= fap <= 68 and math.isfinite(v) and abs(v) <= 2000 for fap, v in faps.items()):
            raise ConfigError(f"{name}: parameter {key!r}: FAPs must be numbered 3-68 with values within +-2000")
        checked[key] = {"weights": weights, "faps": faps}
    return checked


def face_targets(pleasure: float, arousal: float, dominance: float,
                 face_map: Mapping[str, dict] | None = None) -> dict[int, float]:
    """FAP -> value of one PAD state's partial expression (the sum over the map's parameters).

    Examples
    --------
    >>> targets = face_targets(0.0, 1.0, 0.0)  # aroused: brows up, eyes open
    >>> targets[31] > 0 and targets[19] < 0
    True
    """
    targets: dict[int, float] = {}
    for entry in (face_map or DEFAULT_FACE_MAP).values():
        level = float(np.dot(entry["weights"], (pleasure, arousal, dominance)))
        for fap, value in entry["faps"].items():
            targets[int(fap)] = targets.get(int(fap), 0.0) + level * value
    return targets


def pad_face_curves(segments: Sequence[PadSegment], n_frames: int, *, fps: float,
                    face_map: Mapping[str, dict] | None = None) -> dict[int, np.ndarray]:
    """The partial expressions of timed PAD states over a frame grid, blended as expressions are."""
    timed = [(s.start_s, s.end_s, face_targets(s.pleasure, s.arousal, s.dominance, face_map)) for s in segments]
    return blend_targets(timed, n_frames, fps=fps)
