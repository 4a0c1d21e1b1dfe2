"""The whole face: a condition's prosody (brows and head) with the lips and an expression put together.

The lips and the expression do not depend on the condition: every condition of a comparison gets the same
ones, so that only prosody differs between them (as the thesis kept the recorded lips in all four).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..fap.stream import FapStream
from .expressions import ExpressionSegment, add_brow_raises, expression_curves, mix_with_lips
from .lips import lip_curves


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
               mouth_model=None) -> FaceLayer:
    """The lips (``lips``: "visemes", "acoustic" or None) and the expressions of a recording, mixed by seed 000's
    Eq. 14 (see :mod:`prosody.motion.expressions`)."""
    curves: dict[int, np.ndarray] = {}
    if lips is not None:
        curves = lip_curves(audio, n_frames, fps=fps, method=lips, transcript=transcript, gain=lip_gain,
                            mouth_model=mouth_model)
    if expressions:
        curves = mix_with_lips(curves, expression_curves(expressions, n_frames, fps=fps))
    return FaceLayer(curves)
