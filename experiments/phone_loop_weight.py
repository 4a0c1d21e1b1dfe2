"""The phone loop's language weight for the default lips, chosen leaving each speaker out (``make evaluate``).

The phone loop (``audio_features.phones``: PocketSphinx's US English phones, no transcript) weighs its phone
bigram model against the acoustic model by ``lw``; a lower weight trusts the sound more. The weight was chosen
with the hand-set openings; the openings are now fitted to people (``experiments/viseme_fit.py``), and a fit
and a weight go together, so this chooses the weight again with the fit made for each.

Data and measure: those of ``experiments/viseme_fit.py`` (the 30 talking-video speakers and the five
talking-heads speakers). For each weight of :data:`WEIGHTS`, every clip's phones are recognised with it, and
each speaker's lips come from openings fitted on every other speaker's clips (the shipped recipe); a speaker's
opening r is the mean over their clips (best lag within +-0.25 s, as ``experiments/mouth_videos_loso.py``).

The weight is chosen the same way: for each speaker, the weight whose held-out opening r is highest over the
**other** speakers (videos and talking heads, each speaker counted once), and that speaker is scored with it.
So no speaker's score comes from a weight or an opening chosen on them. The phone insertion penalty (``pip``)
is shown at two other values beside the shipped one.

Usage: python -m experiments.phone_loop_weight
"""

from __future__ import annotations

import sys
import warnings
from collections import defaultdict

import numpy as np

from audio_features import phones
from experiments.common import data_folder, phone_loop_settings, record, talking_heads
from experiments.mouth_loco import measured
from experiments.mouth_videos_loso import cell, load_clips
from experiments.viseme_fit import _mouth, _speaker_r, fitting_clips, held_out_visemes

#: The language weights tried (PocketSphinx's default is 6.5).
WEIGHTS = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 4.0, 6.5)
#: Phone insertion penalties tried beside the shipped one, at the shipped weight.
PENALTIES = (0.1, 1.0)
#: The weight chosen with the hand-set openings (on the talking-heads clips).
BEFORE = 2.0


def scored(videos: list[dict], **settings: float) -> dict[str, list]:
    """Per speaker, the measures of each clip's lips (phones recognised with ``settings``, openings fitted on
    the other speakers)."""
    with phone_loop_settings(**settings):
        clips = fitting_clips([{key: value for key, value in clip.items() if key not in ("phones", "lag")}
                               for clip in videos])
    held = held_out_visemes(clips)
    rows: dict[str, list] = defaultdict(list)
    for clip in clips:
        rows[clip["speaker"]].append(measured(*_mouth(clip, held[clip["speaker"]]), clip))
    return rows


def main() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        videos = load_clips()
        shipped = dict(phones.PHONE_LOOP_SETTINGS)
        results = {weight: scored(videos, lw=weight) for weight in WEIGHTS}
        penalties = {pip: scored(videos, pip=pip) for pip in PENALTIES}
    speakers = sorted(results[WEIGHTS[0]])
    names = [s for s in speakers if not s.startswith("heads: ")]
    heads = [s for s in speakers if s.startswith("heads: ")]
    r = {weight: {s: _speaker_r(rows[s]) for s in speakers} for weight, rows in results.items()}
    print(f"{len(names)} talking-video speakers and {len(heads)} talking-heads speakers; phone insertion penalty "
          f"{shipped['pip']:g}; openings fitted without the speaker\n")
    print("| language weight | videos: opening r (control ± spread), closure F1, relative closure F1 | videos: "
          "median speaker's r | talking heads: opening r (control ± spread), closure F1, relative closure F1 |")
    print("|---|---|---|---|")
    for weight in WEIGHTS:
        mark = " (before)" if weight == BEFORE else " (shipped)" if weight == shipped["lw"] else ""
        print(f"| {weight:g}{mark} | {cell(results[weight], names)} | "
              f"{np.median([r[weight][s] for s in names]):.3f} | {cell(results[weight], heads)} |")
    for pip, rows in penalties.items():
        print(f"| {shipped['lw']:g}, insertion penalty {pip:g} | {cell(rows, names)} | "
              f"{np.median([_speaker_r(rows[s]) for s in names]):.3f} | {cell(rows, heads)} |")
    chosen = {s: max(WEIGHTS, key=lambda w: np.mean([r[w][o] for o in speakers if o != s])) for s in speakers}
    nested = np.array([r[chosen[s]][s] for s in names])
    before = np.array([r[BEFORE][s] for s in names])
    counts = {w: sum(1 for s in speakers if chosen[s] == w) for w in WEIGHTS if w in chosen.values()}
    print(f"\nThe weight chosen for each speaker on the other {len(speakers) - 1}: "
          + ", ".join(f"{w:g} for {n} speakers" for w, n in counts.items()))
    print(f"videos, each speaker scored with the weight chosen without them: opening r mean {nested.mean():.3f}, "
          f"median {np.median(nested):.3f} ({np.mean(nested >= 0.3):.0%} of speakers at 0.3 or more); with the "
          f"weight before ({BEFORE:g}): mean {before.mean():.3f}, median {np.median(before):.3f}")
    overall = max(WEIGHTS, key=lambda w: np.mean([r[w][s] for s in speakers]))
    print(f"the weight chosen on every speaker: {overall:g}; the phone loop ships {shipped['lw']:g}")
    gain = nested - before
    print(f"paired by speaker: {gain.mean():+.3f} ± {gain.std(ddof=1) / np.sqrt(gain.size):.3f} (mean ± standard "
          f"error), higher for {int((gain > 0).sum())} of {gain.size} speakers")


if __name__ == "__main__":
    sys.exit(record("phone_loop_weight", main, lambda: [data_folder("talking-videos", needs="the talking videos"),
                                                         talking_heads()]))
