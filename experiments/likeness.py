"""How far the default face moves beside people on the same words (part of ``make evaluate``).

On the clips of ``<shared data>/talking-videos`` tracked by ``prosody track`` (one speaker each, their own
voice), by speaker:

1. **In the stream** (FAP units): the mouth's inner-lip opening (FAP 3 - 4 - 5, MNS) and the inner brow
   (FAP 31, ENS) that ``prosody convert`` makes from the clip's sound, beside the person's tracked opening and
   brow height converted to the same units: the spread ratio (standard deviation, ours over the person's) and
   the mouth's closing (its 5th percentile over its 90th). The gains that would make the spreads equal are
   fitted leave-one-speaker-out (the median ratio of the other speakers) and reported held out.
2. **Through render and tracker:** the default preview (``prosody preview``, no strip, true scale) of the
   first :data:`SECONDS` of each clip, tracked back by ``prosody track``, beside the tracked person: the
   mouth's spread ratio (pass 0.67-1.5), its closing against the person's (within 1.5x), the brows' spread
   ratio (0.5-1.5), and the mouth's r with the person's (>= 0.3) by the shared mouth measure
   (``prosody.measures.mouth_metrics``: the person's opening low-passed at 8 Hz, the best lag within +-0.25 s,
   which absorbs the clips' own sound-to-picture offsets); control: the same render circularly shifted
   against the person at that lag (mean and spread over speakers). The r is also given over the speakers
   whose tracked opening is a reliable reference (its two measures, the inner-lip landmarks and MediaPipe's
   jawOpen, agree at r >= 0.8 over the same frames, as in ``experiments/mouth_videos_loso.py``): a noisy
   reference lowers any r, whatever the lips.

The visemes' openings are fitted for each speaker without that speaker (``experiments/viseme_fit.py``, the
shipped openings' recipe), and with ``--lips acoustic`` or ``--lips combined`` the acoustic mouth model is
refitted for each speaker without that speaker (the shipped model's recipe: the talking-heads clips and the other
video speakers), so no figure comes from a model that heard the person.

``python -m experiments.likeness [--stream-only] [--speakers N] [--lips METHOD]``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

from experiments.common import TRACKED_VIDEOS, data_folder, record, tracked_videos
from experiments.mouth_videos_loso import RELIABLE_AGREEMENT, speakers
from prosody.fap.recorded import read_brows_csv, read_mouth_csv
from prosody.measures import mouth_metrics, opening_agreement
from prosody.motion.face.lips import MNS_PER_EYE_WIDTH, inner_opening
from prosody.motion.settings import LIP_METHODS, FaceSettings

FPS = 30.0
SECONDS = 20.0
PASS = {"mouth spread": (0.67, 1.5), "closing ratio": (1 / 1.5, 1.5), "brow spread": (0.5, 1.5), "mouth r": 0.3}


def _spread(values: np.ndarray) -> float:
    return float(np.nanstd(values))


def _closing(opening: np.ndarray) -> float:
    """5th percentile over 90th: 0 for a mouth that closes fully, near 1 for one that never does."""
    low, high = np.nanpercentile(opening, [5, 90])
    return float(low / high) if high > 0 else float("nan")


def _mouth_r(ours: np.ndarray, person: np.ndarray) -> tuple[float, float]:
    """The opening r of our tracked mouth with the person's (the shared measure, best lag within +-0.25 s),
    and the control: ours circularly shifted by a third and two thirds of the clip, at that lag."""
    ours = np.nan_to_num(np.asarray(ours, float), nan=float(np.nanmedian(ours)))
    n = min(ours.size, person.size)
    ours, person = ours[:n], person[:n]
    flat = np.zeros(n)
    result = mouth_metrics(ours, flat, person, flat, fps=FPS)
    lag = int(round(result["lag_s"] * FPS))
    controls = [mouth_metrics(np.roll(ours, n * k // 3), flat, person, flat, fps=FPS, lag_frames=lag)["opening_r"]
                for k in (1, 2)]
    controls = [c for c in controls if c is not None]
    return (float("nan") if result["opening_r"] is None else float(result["opening_r"]),
            float(np.mean(controls)) if controls else float("nan"))


def clips(limit: int | None) -> list[dict]:
    """One clip per speaker (the longest), with the face found in >= 80 % of its frames."""
    tracked_videos()
    who = speakers()
    best: dict[str, dict] = {}
    for mouth_file in sorted(TRACKED_VIDEOS.glob("*.mouth.csv")):
        stem = mouth_file.name[: -len(".mouth.csv")]
        if stem not in who:
            continue
        mouth = read_mouth_csv(mouth_file)
        if np.isfinite(mouth.lip_opening).mean() < 0.8:
            continue
        entry = {"name": stem, "speaker": who[stem]["speaker"], "sex": who[stem]["sex"], "mouth": mouth,
                 "brows": read_brows_csv(TRACKED_VIDEOS / f"{stem}.brows.csv"), "audio": TRACKED_VIDEOS / f"{stem}.wav"}
        speaker = entry["speaker"]
        if speaker not in best or len(mouth.lip_opening) > len(best[speaker]["mouth"].lip_opening):
            best[speaker] = entry
    chosen = sorted(best.values(), key=lambda clip: clip["name"])
    return chosen[:limit] if limit else chosen


def held_out_models(chosen: list[dict], folder: Path) -> dict[str, Path]:
    """Per speaker, an acoustic mouth model fitted without that speaker's clips, saved in ``folder``."""
    from experiments.mouth_videos_loso import heads_training, load_clips
    from prosody.motion.face.mouth_model import AcousticMouthModel

    heads = heads_training()
    training = load_clips()
    paths = {}
    for clip in chosen:
        speaker = clip["speaker"]
        paths[speaker] = folder / f"mouth-without-{len(paths)}.json"
        AcousticMouthModel().fit(heads + [c["training"] for c in training if c["speaker"] != speaker]).save(
            paths[speaker])
    return paths


def stream_level(chosen: list[dict], lips: str = "visemes") -> dict[str, dict]:
    """Per speaker: spreads and closings of ours and the person's, in FAP units."""
    from experiments.viseme_fit import held_out_openings, using_visemes
    from prosody.jobs.pipeline import convert

    out = {}
    visemes = held_out_openings()  # the shipped openings' recipe, without the speaker
    with tempfile.TemporaryDirectory() as folder:
        models = held_out_models(chosen, Path(folder)) if lips in ("acoustic", "combined") else {}
        streams = {}
        for clip in chosen:
            model = models.get(clip["speaker"])
            with warnings.catch_warnings(), using_visemes(visemes[clip["speaker"]]):
                warnings.simplefilter("ignore")
                streams[clip["speaker"]] = convert(clip["audio"], None, lips=lips,
                                                   **({"mouth_model": str(model)} if model else {}))
    for clip in chosen:
        stream = streams[clip["speaker"]]
        n = min(stream.n_frames, len(clip["mouth"].lip_opening))
        ours_open = inner_opening({f: stream.curve(f) for f in (3, 4, 5)})[:n]
        person_open = clip["mouth"].lip_opening[:n] / MNS_PER_EYE_WIDTH * 1024.0
        ours_brow = stream.curve(31)[:n]
        person_brow = clip["brows"].curve(31)[:n]
        stream_r, stream_control = _mouth_r(ours_open[: int(SECONDS * FPS)], person_open[: int(SECONDS * FPS)])
        out[clip["speaker"]] = {"stream": stream, "mouth ours": _spread(ours_open), "mouth r": stream_r,
                                "control r": stream_control,
                                "mouth person": _spread(person_open), "closing ours": _closing(ours_open),
                                "closing person": _closing(person_open), "brow ours": _spread(ours_brow),
                                "brow person": _spread(person_brow), "sex": clip["sex"]}
    return out


def held_out_gains(level: dict[str, dict], key: str) -> dict[str, float]:
    """Per speaker, the gain that makes our spread the person's: the median ratio of the other speakers."""
    ratios = {s: v[f"{key} person"] / v[f"{key} ours"] for s, v in level.items() if v[f"{key} ours"] > 0}
    return {s: float(np.median([r for other, r in ratios.items() if other != s])) for s in ratios}


def print_stream_level(level: dict[str, dict]) -> None:
    print("## In the stream (FAP units), by speaker\n")
    print("| | mouth spread, ours / person's | mouth closing, ours (person's) | brow spread, ours / person's "
          f"| mouth r, first {SECONDS:g} s (control) |")
    print("|---|---|---|---|---|")
    for speaker, v in level.items():
        print(f"| {speaker} ({v['sex']}) | {v['mouth ours'] / v['mouth person']:.2f} | {v['closing ours']:.2f} "
              f"({v['closing person']:.2f}) | {v['brow ours'] / max(v['brow person'], 1e-9):.2f} "
              f"| {v['mouth r']:.2f} ({v['control r']:+.2f}) |")
    stream_r = [v["mouth r"] for v in level.values()]
    print(f"\nmouth r in the stream, first {SECONDS:g} s: median {np.median(stream_r):.2f}, "
          f"mean {np.mean(stream_r):.3f} (control {np.mean([v['control r'] for v in level.values()]):+.2f})")
    for key, unit in (("mouth", "opening"), ("brow", "inner brow")):
        ratios = np.array([v[f"{key} ours"] / v[f"{key} person"] for v in level.values() if v[f"{key} person"] > 0])
        gains = held_out_gains(level, key)
        held = np.array([level[s][f"{key} ours"] * g / level[s][f"{key} person"] for s, g in gains.items()])
        print(f"\n{unit}: spread ratio median {np.median(ratios):.2f} (range {ratios.min():.2f}-{ratios.max():.2f}); "
              f"gain fitted leaving each speaker out: median {np.median(list(gains.values())):.2f} (range "
              f"{min(gains.values()):.2f}-{max(gains.values()):.2f}); spread ratio with it, held out: median "
              f"{np.median(held):.2f}, {np.mean((held >= 0.67) & (held <= 1.5)):.0%} of speakers in 0.67-1.5")


def through_render(chosen: list[dict], level: dict[str, dict]) -> None:
    from prosody.evaluation.preview import write_preview

    rows = []
    with tempfile.TemporaryDirectory() as folder:
        work = Path(folder)
        for clip in chosen:
            stream = level[clip["speaker"]]["stream"]
            video = work / f"{clip['name']}.mp4"
            write_preview(stream, video, audio=clip["audio"], duration_s=SECONDS, strip=False, captioned=False,
                          brow_scale=1.0, width=480)
            subprocess.run([sys.executable, "-m", "prosody", "track", str(video), "-o", str(work / "tracked"), "-q"],
                           check=True)
            ours_mouth = read_mouth_csv(work / "tracked" / f"{clip['name']}.mouth.csv")
            ours_brows = read_brows_csv(work / "tracked" / f"{clip['name']}.brows.csv")
            n = len(ours_mouth.lip_opening)
            person = clip["mouth"].lip_opening[:n]
            jaw_open = clip["mouth"].jaw_open
            agreement = (opening_agreement(person, jaw_open[:n], fps=FPS) if jaw_open is not None else None)
            rows.append({"clip": clip, "ours": ours_mouth.lip_opening, "person": person, "agreement": agreement,
                         "mouth spread": _spread(ours_mouth.lip_opening) / _spread(person),
                         "closing ours": _closing(ours_mouth.lip_opening), "closing person": _closing(person),
                         "brow spread": _spread(ours_brows.curve(31)) / max(_spread(clip["brows"].curve(31)[:n]), 1e-9),
                         **dict(zip(("mouth r", "control r"), _mouth_r(ours_mouth.lip_opening, person), strict=True))})
    print(f"\n## Through render and tracker: the default preview of the first {SECONDS:g} s, tracked back\n")
    print("| speaker | mouth spread ratio | closing, ours (person's) | brow spread ratio | mouth r | control r |")
    print("|---|---|---|---|---|---|")
    for row in rows:
        clip = row["clip"]
        print(f"| {clip['speaker']} ({clip['sex']}) | {row['mouth spread']:.2f} | {row['closing ours']:.2f} "
              f"({row['closing person']:.2f}) | {row['brow spread']:.2f} | {row['mouth r']:.2f} | "
              f"{row['control r']:+.2f} |")

    def share(values, low, high) -> str:
        values = np.asarray(values)
        inside = np.mean((values >= low) & (values <= high))
        return f"median {np.median(values):.2f}, {inside:.0%} in {low:.2f}-{high:.2f}"

    closing = [r["closing ours"] / r["closing person"] for r in rows if r["closing person"] > 0]
    controls = np.array([r["control r"] for r in rows])
    reliable = [r for r in rows if r["agreement"] is not None and r["agreement"] >= RELIABLE_AGREEMENT]
    print(f"\nmouth spread ratio: {share([r['mouth spread'] for r in rows], *PASS['mouth spread'])}")
    print(f"closing, ours over the person's: {share(closing, *PASS['closing ratio'])}")
    print(f"brow spread ratio: {share([r['brow spread'] for r in rows], *PASS['brow spread'])}")
    mouth_r = [r["mouth r"] for r in rows]
    print(f"mouth r: median {np.median(mouth_r):.2f}, mean {np.mean(mouth_r):.3f} (control {np.mean(controls):+.2f} ± "
          f"{np.std(controls):.2f}); {np.mean([r >= PASS['mouth r'] for r in mouth_r]):.0%} of speakers >= 0.3")
    if reliable:
        print(f"mouth r where the person's tracked opening is a reliable reference (its inner-lip and jawOpen "
              f"measures agree at r >= {RELIABLE_AGREEMENT} over these frames; {len(reliable)} of {len(rows)} "
              f"speakers): median {np.median([r['mouth r'] for r in reliable]):.2f} (control "
              f"{np.mean([r['control r'] for r in reliable]):+.2f}); "
              f"{np.mean([r['mouth r'] >= PASS['mouth r'] for r in reliable]):.0%} of them >= 0.3")
    for key, name in (("mouth spread", "the mouth's opening"), ("brow spread", "the brows")):
        ratios = {row["clip"]["speaker"]: row[key] for row in rows if row[key] > 0}
        gains = {s: float(np.median([1 / r for other, r in ratios.items() if other != s])) for s in ratios}
        print(f"gain on {name} that would match the people's spread, fitted leaving each speaker out: median "
              f"{np.median(list(gains.values())):.2f} (range {min(gains.values()):.2f}-{max(gains.values()):.2f}); "
              f"held out, the spread ratio with it: {share([ratios[s] * g for s, g in gains.items()], *PASS[key])}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stream-only", action="store_true", help="the stream-level table alone (no render)")
    parser.add_argument("--speakers", type=int, default=None, help="only the first N speakers")
    parser.add_argument("--lips", choices=LIP_METHODS, default=FaceSettings().lips,
                        help="the lips (default: the default's); acoustic ones refitted without each speaker")
    args = parser.parse_args(argv)
    chosen = clips(args.speakers)
    print(f"{len(chosen)} speakers of the talking videos, one clip each (the longest), the default settings"
          f"{'' if args.lips == FaceSettings().lips else f' but --lips {args.lips}'} (lips: {args.lips}"
          f"{', its acoustic model refitted without each speaker' if args.lips != 'visemes' else ''})\n")
    level = stream_level(chosen, args.lips)
    print_stream_level(level)
    if not args.stream_only:
        through_render(chosen, level)
    return 0


if __name__ == "__main__":
    sys.exit(record("likeness", lambda: main(sys.argv[1:]),
                    lambda: [data_folder("talking-videos", needs="the talking-videos clips")]))
