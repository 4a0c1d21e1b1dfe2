"""Leave-one-speaker-out table of the live (causal) head beside the offline one, and the live brows'
agreement with the offline rule (part of ``make evaluate``).

For each look-ahead, the live head model is fitted on every other speaker's recordings (their audio analysed
as a stream; ``experiments/speakers.csv``) and measured on this speaker's over 10 seeds, beside the
mismatched-audio control (the same model driven by the recording's own frames circularly shifted by 5 s or
more) and its chance spread (the standard deviation over recordings). The row "nested" chooses the settings
(presence window, pitch follow) inside each fold, on the other speakers' recordings only; the row "pitch
taken at once" is the head without its pitch follower, as before it existed. The brows: raise onsets of the
live rule within 3 frames (100 ms) of the offline rule's, over the talking-head clips and the speech
recordings.

A second table adds the talking-videos clips tracked by ``experiments/head_loso.py`` (when it has run).

Usage: python -m experiments.live_loco [DIR] [--no-tracked]  (default ../shared/data/talking-heads)
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

from audio_features import extract_features
from audio_features.streaming import stream_file
from experiments.common import record, talking_heads
from experiments.head_loco import default_data
from experiments.head_loso import TRACKED, row, speakers
from prosody.motion.eyebrows import AccentRule, EyebrowRule, brow_raises
from prosody.motion.heads.live import live_brows
from prosody.motion.heads.live_training import held_out_live, load_streamed, nested_held_out_live, speaker_folds
from prosody.motion.heads.training import find_pairs

LOOKAHEADS_MS = (0, 100, 200, 300, 500)


def brow_agreement(paths: list[Path], lookahead: int) -> dict[str, tuple[int, int]]:
    """Per rule: (offline onsets with a live onset within 3 frames, offline onsets)."""
    counts = {"accent": [0, 0], "thesis": [0, 0]}
    for path in paths:
        offline_features = extract_features(path)
        f0, energy = stream_file(str(path))
        for name, rule in (("accent", AccentRule()), ("thesis", EyebrowRule())):
            offline = [start for start, _ in brow_raises(offline_features, rule).events]
            live = live_brows(rule, fps=30.0, lookahead=lookahead)
            for a, b in zip(f0, energy, strict=True):
                live.push(a, b)
            live.finish()
            onsets = [start for start, _ in live.events]
            counts[name][0] += sum(any(abs(s - t) <= 3 for t in onsets) for s in offline)
            counts[name][1] += len(offline)
    return {name: (matched, total) for name, (matched, total) in counts.items()}


def main(argv: list[str]) -> int:
    directory = Path(argv[0]) if argv and not argv[0].startswith("--") else default_data()
    warnings.simplefilter("ignore")
    table = speakers()
    recordings = load_streamed(find_pairs(directory), report=lambda message: None, speakers=table)
    print(f"{len(recordings)} recordings of {len(speaker_folds(recordings))} speakers analysed as streams, "
          "leave-one-speaker-out, 10 seeds")
    header = ("| live head | clips | speed-envelope r | pitch r | std ratio pitch / yaw / roll "
              "| velocity-spectrum distance (dB) | speed p10 / p50 / p90 ratio | still: generated vs recorded "
              "| held pose from median (deg): generated vs recorded "
              "| control: speed-envelope r (chance spread) | control: pitch r (chance spread) |\n"
              "|---|---|---|---|---|---|---|---|---|---|---|")
    print()
    print(header)
    for ms in LOOKAHEADS_MS:
        result = held_out_live(recordings, lookahead_s=ms / 1000)
        print(row(f"{ms} ms look-ahead", list(result.per_recording.values()), list(result.controls.values())))
    result = held_out_live(recordings, lookahead_s=0.1, pitch_follow_s=0.0)
    print(row("100 ms, pitch taken at once (pitch_follow_s 0)", list(result.per_recording.values()),
              list(result.controls.values())))
    nested = nested_held_out_live(recordings, lookahead_s=0.1)
    print(row("100 ms, settings chosen per fold (nested)", list(nested.per_recording.values()),
              list(nested.controls.values())))
    if "--no-tracked" not in argv and TRACKED.is_dir():
        # every speaker at hand: the talking-videos clips tracked by experiments/head_loso.py as well
        tracked = load_streamed(find_pairs(TRACKED), report=lambda message: None, speakers=table)
        everyone = recordings + tracked
        print()
        print(f"With the tracked talking-videos clips: {len(everyone)} recordings of "
              f"{len(speaker_folds(everyone))} speakers, leave-one-speaker-out, 10 seeds")
        print()
        print(header)
        names = {r.name for r in recordings}
        for label, settings in (("0 ms", {"lookahead_s": 0.0}), ("100 ms", {"lookahead_s": 0.1}),
                                ("100 ms, pitch_follow_s 0", {"lookahead_s": 0.1, "pitch_follow_s": 0.0})):
            result = held_out_live(everyone, **settings)
            for clips, chosen in (("all", [r.name for r in everyone]), ("talking-heads", sorted(names)),
                                  ("talking-videos", [r.name for r in tracked])):
                print(row(f"{label}: {clips}", [result.per_recording[n] for n in chosen],
                          [result.controls[n] for n in chosen]))
    print()
    speech = sorted(directory.glob("*.wav")) + sorted((directory.parent / "speech").glob("*.wav"))
    print("Live brows against the offline rule (onsets within 3 frames / offline onsets):")
    for ms in (0, 100, 200):
        agreement = brow_agreement(speech, int(round(ms * 0.03)))
        cells = [f"{name} {matched}/{total} ({matched / max(total, 1):.0%})"
                 for name, (matched, total) in agreement.items()]
        print(f"  {ms:3d} ms look-ahead: " + ", ".join(cells))
    frames = [(extract_features(path).n_frames, stream_file(str(path))[0].size) for path in speech]
    print(f"Frame counts equal to the offline analysis on {sum(a == b for a, b in frames)} of {len(frames)} files")
    return 0


if __name__ == "__main__":
    given = [Path(argument) for argument in sys.argv[1:2] if not argument.startswith("-")]
    sys.exit(record("live_loco", lambda: main(sys.argv[1:]), lambda: given or [talking_heads()]))
