"""Would a higher voice's phones be heard better with its spectrum warped to a lower one? (``make evaluate``)

Vocal-tract length normalisation: PocketSphinx's front end can scale the frequency axis before its filter
bank (``warp_type inverse_linear``: a frequency f is read as f / alpha), so that a shorter vocal tract's higher
formants fall where its English model, trained mostly on adult voices, expects them. Every method here is
fixed in advance (nothing is fitted to a mouth):

- no warp (the shipped phone loop);
- one warp for every voice, alpha 1.1, 1.2 and 1.3;
- a warp from the voice's pitch: alpha = (median F0 / 132 Hz) ** 0.30, kept within 0.9-1.3. The exponent is
  Peterson and Barney's averages (1952): women's formants about 17 % above men's for a median F0 of 223 Hz
  against 132 Hz, ln 1.17 / ln (223 / 132) = 0.30.

The default visemes from each warp's phones are measured against the tracked mouths as
``experiments/mouth_videos_loso.py`` measures them: first on the seven talking-heads clips (where a warp would
be chosen), then on the 30 speakers of the talking videos, each speaker's clips averaged first, women and men
apart, with the control (the lips shifted against the recording) and its spread.

Usage: python -m experiments.phone_warp
"""

from __future__ import annotations

import contextlib
import sys
import warnings
from collections import defaultdict

import numpy as np

import audio_features.phones as phones
from audio_features import extract_features, load_audio
from experiments.common import data_folder, phone_loop_settings, record
from experiments.mouth_videos_loso import FPS, load_clips, measured, summary_table
from prosody.fap.recorded import read_mouth_csv
from prosody.motion.face.lips import inner_opening, shape_faps, shapes_from_phones

#: Peterson and Barney's (1952) mean F0 of men, Hz, and the exponent that turns a pitch ratio into their
#: women's-to-men's formant ratio.
MEN_F0_HZ, PITCH_TO_FORMANT = 132.0, 0.30
FIXED_WARPS = (1.1, 1.2, 1.3)


@contextlib.contextmanager
def warped(alpha: float | None):
    """The phone loop with its front end's frequency axis divided by ``alpha`` (None: as shipped)."""
    with phone_loop_settings(**({} if alpha is None else {"warp_type": "inverse_linear",
                                                         "warp_params": f"{alpha:.3f}"})):
        yield


def pitch_warp(audio) -> float:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        f0 = extract_features(audio, fps=100.0).f0.values
    median = float(np.nanmedian(f0)) if np.isfinite(f0).any() else MEN_F0_HZ
    return float(np.clip((median / MEN_F0_HZ) ** PITCH_TO_FORMANT, 0.9, 1.3))


def visemes_measured(clip: dict, alpha: float | None) -> tuple[dict, dict]:
    n = clip["mouth"].n_frames
    with warped(alpha):
        faps = shape_faps(shapes_from_phones(phones.recognise_phones(clip["audio"]), n, fps=FPS))
    return measured(inner_opening(faps)[:n], faps[16][:n], clip)


def main() -> None:
    methods: dict[str, object] = {"no warp (shipped)": None}
    methods |= {f"alpha {alpha}": alpha for alpha in FIXED_WARPS}
    methods["alpha from the pitch"] = pitch_warp

    def alpha_of(method, clip: dict) -> float | None:
        return method(clip["audio"]) if callable(method) else method

    folder = data_folder("talking-heads", needs="the talking-heads clips")
    heads = [{"name": wav.stem, "audio": load_audio(wav), "mouth": read_mouth_csv(wav.with_suffix(".mouth.csv"))}
             for wav in sorted(folder.glob("*.wav")) if wav.with_suffix(".mouth.csv").is_file()]
    print(f"The {len(heads)} talking-heads clips ({', '.join(c['name'] for c in heads)}), opening r of the "
          "default visemes:\n")
    print("| phones | " + " | ".join(c["name"] for c in heads) + " | mean |")
    print("|---" * (len(heads) + 2) + "|")
    for label, method in methods.items():
        values = [visemes_measured(clip, alpha_of(method, clip))[0]["opening_r"] for clip in heads]
        print(f"| {label} | " + " | ".join(f"{v:.2f}" for v in values) + f" | {np.mean(values):.3f} |")

    clips = load_clips()
    sexes = {clip["speaker"]: clip["sex"] for clip in clips}
    print(f"\nThe talking videos: {len(clips)} clips, {len(sexes)} speakers\n")
    rows: dict[str, dict[str, list]] = {label: defaultdict(list) for label in methods}
    for label, method in methods.items():
        for clip in clips:
            rows[label][clip["speaker"]].append(visemes_measured(clip, alpha_of(method, clip)))
    summary_table("phones", {label: label for label in methods}, rows, sexes)


if __name__ == "__main__":
    sys.exit(record("phone_warp", main, lambda: [data_folder("talking-heads", needs="the talking-heads clips"),
                                                 data_folder("talking-videos", needs="the talking videos")]))
