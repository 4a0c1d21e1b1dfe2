"""Does a richer learner than ridge pay for the acoustic lips on speakers left out? (``make evaluate``)

The 30 speakers of the shared talking videos (as ``experiments/mouth_videos_loso.py`` tracks them), each held
out in turn: the acoustic mouth model's features (13 MFCCs and log energy at 13 offsets over +-0.3 s,
standardised per recording) mapped to the tracked mouth by ridge regressions (the shipped learner, at its
penalty and at ten times it) and by small neural networks (scikit-learn's MLPRegressor, one hidden layer of 32
or 64 units or two of 128 and 64, early stopping on a tenth of the training frames, seed 0), trained on the
seven talking-heads clips and the other speakers. Means over speakers of the opening r (with the control: the
lips shifted in time, and its spread) and the closure F1, for women and men apart. Last, the shipped ridge fitted
on the talking-heads clips and only those video clips whose tracked mouth is a reliable reference (the two
measures of its opening agree at 0.6, 0.7 or 0.8 or better), measured on every clip held out.

Needs scikit-learn (it comes with librosa, in the ``languages`` and ``track`` extras).
"""

from __future__ import annotations

import sys
import warnings
from collections import defaultdict

import numpy as np

from experiments.common import data_folder, record
from experiments.mouth_videos_loso import FPS, heads_training, load_clips, measured, summary_table
from prosody.motion.face.lips import MouthShape, inner_opening, shape_faps
from prosody.motion.face.mouth_model import AcousticMouthModel


class NetworkMouthModel(AcousticMouthModel):
    """The acoustic mouth model with a small neural network in place of the ridge regressions."""

    def __init__(self, hidden: tuple[int, ...], alpha: float) -> None:
        super().__init__()
        self.hidden, self.alpha = hidden, alpha

    def fit(self, clips: list) -> NetworkMouthModel:
        from sklearn.neural_network import MLPRegressor

        x = np.vstack([clip.features for clip in clips])
        y = np.column_stack([np.concatenate([getattr(clip, key) for clip in clips])
                             for key in ("opening", "rounding", "spread")])
        known = np.isfinite(y).all(axis=1)
        x, y = x[known], y[known]
        self.mean_, self.spread_ = y.mean(axis=0), y.std(axis=0) + 1e-9
        self.network_ = MLPRegressor(hidden_layer_sizes=self.hidden, alpha=self.alpha, early_stopping=True,
                                     random_state=0, max_iter=300, batch_size=256)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # convergence notes of early stopping
            self.network_.fit(x, (y - self.mean_) / self.spread_)
        return self

    def predict_features(self, features: np.ndarray) -> MouthShape:
        shape = self.network_.predict(features) * self.spread_ + self.mean_
        return MouthShape(np.clip(shape[:, 0], 0.0, None), shape[:, 1], shape[:, 2])


LEARNERS = {
    "ridge, penalty 100 (shipped)": lambda: AcousticMouthModel(ridge=100.0),
    "ridge, penalty 1000": lambda: AcousticMouthModel(ridge=1000.0),
    "network, 32 units, alpha 0.01": lambda: NetworkMouthModel((32,), 1e-2),
    "network, 64 units, alpha 0.001": lambda: NetworkMouthModel((64,), 1e-3),
    "network, 128 and 64 units, alpha 0.01": lambda: NetworkMouthModel((128, 64), 1e-2),
}
#: The shipped ridge again, fitted only on the video clips whose tracked mouth is a reliable reference: the two
#: measures of its opening agree at least this well (``prosody.measures.opening_agreement``).
RELIABLE_ONLY = (0.6, 0.7, 0.8)


def main() -> int:
    clips = load_clips()
    heads = heads_training()
    speakers = sorted({clip["speaker"] for clip in clips})
    sexes = {clip["speaker"]: clip["sex"] for clip in clips}
    learners = {label: (make, None) for label, make in LEARNERS.items()}
    learners |= {f"ridge, penalty 100, video clips of reference agreement >= {bar} alone":
                 (lambda: AcousticMouthModel(ridge=100.0), bar) for bar in RELIABLE_ONLY}
    rows: dict[str, dict[str, list]] = {label: defaultdict(list) for label in learners}
    for speaker in speakers:
        for label, (make, bar) in learners.items():
            training = heads + [clip["training"] for clip in clips if clip["speaker"] != speaker
                                and (bar is None or (clip["agreement"] is not None and clip["agreement"] >= bar))]
            model = make().fit(training)
            for clip in (c for c in clips if c["speaker"] == speaker):
                n = clip["mouth"].n_frames
                faps = shape_faps(model.predict(clip["audio"], n, fps=FPS))
                rows[label][speaker].append(measured(inner_opening(faps)[:n], faps[16][:n], clip))
    print(f"{len(clips)} clips, {len(speakers)} speakers held out in turn\n")
    summary_table("learner", {label: label for label in learners}, rows, sexes)
    return 0


if __name__ == "__main__":
    sys.exit(record("mouth_learners_loso", main, lambda: [data_folder("talking-videos", needs="the talking videos")]))
