"""The whole face: a condition's prosody (brows and head) with the lips and an expression put together.

The lips and the expression do not depend on the condition: every condition of a comparison gets the same
ones, so that only prosody differs between them (as the thesis kept the recorded lips in all four).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ...errors import ConfigError
from ...fap.stream import FapStream
from .expressions import ExpressionSegment, add_brow_raises, expression_curves, mix_with_lips
from .lips import LIP_METHODS, MouthShape, inner_opening, shape_faps, shapes_from_phones
from .pad import PadSegment, pad_face_curves


@dataclass(frozen=True, eq=False)
class FaceLayer:
    """What the lips and an expression add to a stream: FAP -> curve on its grid."""

    curves: dict[int, np.ndarray]

    def over(self, stream: FapStream) -> FapStream:
        """``stream`` with this layer: the expression's brows under the stream's raises, the rest added."""
        raises = {fap: stream.curve(fap) for fap in stream.active_faps if fap in self.curves and 31 <= fap <= 36}
        curves = dict(self.curves)
        curves.update(add_brow_raises({fap: curves[fap] for fap in raises}, raises))
        return stream.with_curves(curves)


def face_layer(audio, n_frames: int, *, fps: float, lips: str | None = "visemes", transcript: str | None = None,
               lip_gain: float = 1.0, expressions: Sequence[ExpressionSegment] = (),
               mouth_model=None, pad: Sequence[PadSegment] = (), pad_map=None,
               language: str | None = None) -> FaceLayer:
    """The lips (``lips``: one of :data:`LIP_METHODS`, or None), the expressions and the partial expressions of a PAD
    state (:mod:`prosody.motion.face.pad`) of a recording, mixed by Jia et al.'s Eq. 14 (see
    :mod:`prosody.motion.face.expressions`)."""
    curves: dict[int, np.ndarray] = {}
    if lips is not None:
        curves = lip_curves(audio, n_frames, fps=fps, method=lips, transcript=transcript, gain=lip_gain,
                            mouth_model=mouth_model, language=language)
    shown: dict[int, np.ndarray] = expression_curves(expressions, n_frames, fps=fps) if expressions else {}
    if pad:
        for fap, curve in pad_face_curves(pad, n_frames, fps=fps, face_map=pad_map).items():
            shown[fap] = shown[fap] + curve if fap in shown else curve
    if shown:
        curves = mix_with_lips(curves, shown)
    return FaceLayer(curves)


def stream_mouth(stream: FapStream) -> tuple[np.ndarray, np.ndarray] | None:
    """The inner-lip opening (FAP 3 - 4 - 5, MNS) and protrusion (FAP 16 + 17) of a stream with lips, else None."""
    if not all(stream.mask[:, fap - 1].all() for fap in (3, 4, 5)):
        return None
    curves = {fap: stream.curve(fap) for fap in (3, 4, 5)}
    rounding = sum((stream.curve(fap) for fap in (16, 17) if stream.mask[:, fap - 1].all()), np.zeros(stream.n_frames))
    return inner_opening(curves), rounding


#: ``combined`` keeps the visemes' mouth where they close it (an inner-lip opening under this, MNS: about a
#: millimetre).
COMBINED_CLOSED_MNS = 52.5


def lip_curves(audio, n_frames: int, *, fps: float, method: str = "visemes", transcript: str | None = None,
               gain: float = 1.0, mouth_model=None, language: str | None = None) -> dict[int, np.ndarray]:
    """Lip FAPs of a recording on a frame grid.

    Parameters
    ----------
    audio : audio_features.Audio or path
        The recording (a file is read block by block).
    n_frames : int >= 0
    fps : float > 0
    method : {"visemes", "acoustic", "combined"}
        ``visemes``: phones (PocketSphinx) -> MPEG-4 visemes -> dominance blending; ``acoustic``: the acoustic
        mouth model (language independent, ignores ``transcript``); ``combined``: the mean of the two mouths'
        shapes, the visemes' where they close the lips (under :data:`COMBINED_CLOSED_MNS`): held out by speaker
        it follows the opening better than either (see ``docs/languages.md``).
    transcript : str, optional
        What is said, for ``visemes`` and ``combined`` (aligned to the audio; see
        :func:`audio_features.phones.recognise_phones`).
    language : str, optional
        The transcript's language, an eSpeak NG code (``es``, ``de``, ``cmn``, ...): its phones come from eSpeak NG
        and are aligned by :func:`audio_features.espeak.align_transcript` (any language, no acoustic model);
        without it the transcript is English, aligned by PocketSphinx.
    gain : float >= 0
        Scale of every lip FAP (0: a still, closed mouth).
    mouth_model : AcousticMouthModel, optional
        For ``acoustic`` and ``combined``; the shipped one when omitted.

    Returns
    -------
    dict of int to numpy.ndarray
        Lip FAP -> curve in its units.
    """
    if method not in LIP_METHODS:
        raise ConfigError(f"unknown lip method {method!r}; choose {', '.join(LIP_METHODS)}")
    if not (np.isfinite(gain) and 0 <= gain <= 100):
        raise ConfigError(f"lip gain must be a number in [0, 100], got {gain!r}")
    if method == "acoustic":
        if transcript is not None:
            raise ConfigError("the acoustic lips do not read a transcript; use method='visemes' with it")
        return shape_faps(_acoustic_shape(audio, n_frames, fps=fps, mouth_model=mouth_model), gain=gain)
    if language is not None and transcript is None:
        raise ConfigError("a language is the transcript's: give the transcript too (without one, the acoustic "
                          "lips follow any language)")
    shape = _phone_shape(audio, n_frames, fps=fps, transcript=transcript, language=language)
    if method == "combined":
        heard = _acoustic_shape(audio, n_frames, fps=fps, mouth_model=mouth_model)
        closed = shape.opening < COMBINED_CLOSED_MNS
        shape = MouthShape(np.where(closed, shape.opening, 0.5 * (shape.opening + heard.opening)),
                           0.5 * (shape.rounding + heard.rounding), 0.5 * (shape.spread + heard.spread),
                           shape.viseme)
    return shape_faps(shape, gain=gain)


def _acoustic_shape(audio, n_frames: int, *, fps: float, mouth_model=None) -> MouthShape:
    from .mouth_model import AcousticMouthModel

    model = mouth_model if mouth_model is not None else AcousticMouthModel.load()
    return model.predict(audio, n_frames, fps=fps)


def _phone_shape(audio, n_frames: int, *, fps: float, transcript: str | None, language: str | None) -> MouthShape:
    """The visemes' mouth: eSpeak NG's phones aligned to the recording where a language is given, else
    PocketSphinx's (its phone loop, or the transcript aligned)."""
    if language is not None:
        from audio_features.audio import load_audio
        from audio_features.espeak import align_transcript

        recording = audio if hasattr(audio, "samples") else load_audio(audio)
        return shapes_from_phones(align_transcript(recording, transcript or "", language), n_frames, fps=fps)
    from audio_features.phones import recognise_phones

    return shapes_from_phones(recognise_phones(audio, transcript=transcript), n_frames, fps=fps)
