"""The photo head's closed loop and its likeness to the photo (part of ``make evaluate``).

For each of several people of ``<shared data>/talking-videos`` (women and men), frames of their clip drawn at
random (``--frames``, 3 by default, from ``--seed``) each become the head (:func:`prosody.head.photo.photo_head`):

- **the photo kept:** a still stream's frame against the photo, SSIM of the grey images (scikit-image's
  ``structural_similarity``) at the photo's size; pass mark 0.8;
- **the closed loop:** known motion (head pitch 9, yaw 14, roll 7 degrees, the jaw to 500 MNS, the brows 250
  ENS, each on its own period) rendered on the photo head by ``prosody preview --face`` and tracked back by
  ``prosody track``: |r| >= 0.9 per head axis with the tracked spread 0.75-1.33 of the true one, the lips
  >= 0.9, the brows >= 0.7, the face found in >= 98 % of frames;
- **the grid folded:** the person layer's cells off the face turned over at the largest turns (yaw +-14,
  pitch +-9 degrees; a turned-over cell shows the photo mirrored and squeezed), summed over the four;
- **the tracker's ruler:** what the tracker reads of the drawn lip opening and inner-brow raise, converted to
  FAP units as the tracked-motion readers convert people's (the slope of read over drawn; 1 is true size). It
  says how far a figure in FAP units from tracked people (``experiments/likeness.py``'s first table) is from
  their true size; the comparison through render and tracker needs no ruler, both sides being read alike.

The control beside each figure is the largest |r| of a tracked curve with a motion it was not given. Each
person-frame passes or fails on its own; the last lines count them, and the people who pass on every frame.
Frame ``j`` of seed ``s`` is frame 0 of seed ``s + j``.
``python -m experiments.photo_loop [--seconds 20] [--seed 0] [--frames 3]``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from experiments.common import data_folder, record
from prosody.evaluation.head_loop import PERIODS_S, folded_cells, known_motion, measure
from prosody.fap.fapfile import write_fap
from prosody.fap.units import AU_PER_DEGREE

#: The people: clip, and who speaks (w: a woman, m: a man).
PEOPLE = (("SadTalker_WDA_KatieHill_000.mp4", "w"), ("Real3DPortrait_May_5s.mp4", "w"),
          ("SadTalker_RD_Radio34_000.mp4", "w"), ("MimicTalk_German_20s.mp4", "m"),
          ("EDTalk_pose_source2.mp4", "m"), ("V-Express_RD_Radio10_0_clip_0.mp4", "m"))
#: The photo head's known motion: smaller turns than the 3D head's loop, those of speech.
PHOTO_AMPLITUDES = {"pitch": 9.0, "yaw": 14.0, "roll": 7.0, "jaw": 500.0, "brows": 250.0}
PASS_SSIM, PASS_BROWS_R = 0.8, 0.7


def grab_frame(video: Path, seed: int, out: Path) -> float:
    """One frame of ``video`` at a time drawn from ``seed`` (in its first 90 %), saved as PNG; the time."""
    import av
    from PIL import Image

    with av.open(str(video)) as container:
        stream = container.streams.video[0]
        duration = float(stream.duration * stream.time_base) if stream.duration else float(container.duration) / 1e6
        at = float(np.random.default_rng(seed).uniform(0.05, 0.9) * duration)
        container.seek(int(at / stream.time_base), stream=stream)
        for frame in container.decode(stream):
            if frame.time is None or frame.time >= at - 0.05:
                Image.fromarray(frame.to_ndarray(format="rgb24")).save(out)
                return float(frame.time or at)
    raise SystemExit(f"{video}: no frame at {at:.2f} s")


def ssim_still(photo: Path) -> tuple[float, tuple[int, int], bool, int]:
    """SSIM (grey) of a still stream's frame against the photo, at the photo's size; whether the photo head
    notes the brows raised in the photo; and its person layer's cells off the face turned over at the loop's
    largest turns (yaw either way, then pitch either way; :func:`prosody.evaluation.head_loop.folded_cells`)."""
    from skimage.metrics import structural_similarity

    from prosody.head.photo import PhotoRenderer, photo_head

    head = photo_head(photo)
    renderer = PhotoRenderer(head)
    frame = renderer.render(np.zeros(68))
    grey = np.array([0.299, 0.587, 0.114])
    raised = any("brows are raised" in note for note in head.notes)
    folded = 0
    for fap, axis in ((49, "yaw"), (48, "pitch")):
        for sign in (1, -1):
            values = np.zeros(68)
            values[fap - 1] = sign * PHOTO_AMPLITUDES[axis] * AU_PER_DEGREE
            folded += folded_cells(renderer, values)
    ssim = float(structural_similarity(frame @ grey, head.image @ grey, data_range=255.0))
    return ssim, frame.shape[:2], raised, folded


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--frames", type=int, default=3, help="frames of each person's clip, each a photo")
    parser.add_argument("--keep", default=None, help="copy the photos, videos and tracks to this folder")
    parser.add_argument("--only", default=None, help="only the clips whose name holds this text")
    args = parser.parse_args(argv)
    videos = data_folder("talking-videos", needs="the talking-videos clips")
    from prosody.evaluation import head_loop

    stream = known_motion(args.seconds, amplitudes=PHOTO_AMPLITUDES)
    print(f"photo head closed loop: {args.seconds:g} s at 30 fps per person; motion "
          + ", ".join(f"{k} {PHOTO_AMPLITUDES[k]:g} / {PERIODS_S[k]:g} s" for k in PHOTO_AMPLITUDES)
          + f" (deg, MNS, ENS / period); frames drawn with seed {args.seed}")
    print("| person | frame at | size | SSIM still | found | pitch r / spread | yaw r / spread | roll r / spread "
          "| lips r | brows r | lips read at | brows read at | control |r| | brows raised in photo | cells folded "
          "| pass |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    failures = measured = 0
    passes: dict[str, list[bool]] = {}
    summary: dict[str, list[float]] = {}
    with tempfile.TemporaryDirectory() as folder:
        work = Path(folder)
        write_fap(stream, work / "loop.fap")
        people = [(index, clip, who, j) for index, (clip, who) in enumerate(PEOPLE) for j in range(args.frames)]
        for index, clip, who, j in people:
            name = Path(clip).stem
            if args.only and args.only not in name:
                continue
            photo = work / f"{name}.png"
            at = grab_frame(videos / clip, (args.seed + j) * 1000 + index, photo)
            ssim, size, raised, folded = ssim_still(photo)
            subprocess.run([sys.executable, "-m", "prosody", "preview", str(work / "loop.fap"), "-o",
                            str(work / f"{name}.mp4"), "--face", str(photo), "--brow-scale", "1", "--no-strip",
                            "-q"], check=True)
            subprocess.run([sys.executable, "-m", "prosody", "track", str(work / f"{name}.mp4"), "-o",
                            str(work / "tracked"), "-q"], check=True)
            result = measure(stream, work / "tracked" / name)
            if args.keep:
                import shutil

                shutil.copytree(work, args.keep, dirs_exist_ok=True)
            head_ok = all(abs(r) >= head_loop.PASS_HEAD_R for r in result.head_r.values()) and all(
                head_loop.PASS_SPREAD[0] <= s <= head_loop.PASS_SPREAD[1] for s in result.head_spread.values())
            passed = (head_ok and result.lips_r >= head_loop.PASS_LIPS_R and result.brows_r >= PASS_BROWS_R
                      and result.found >= head_loop.PASS_FOUND and ssim >= PASS_SSIM)
            failures += not passed
            measured += 1
            passes.setdefault(name, []).append(passed)
            axes = " | ".join(f"{result.head_r[a]:.3f} / {result.head_spread[a]:.2f}" for a in ("pitch", "yaw", "roll"))
            print(f"| {name} ({who}) | {at:.2f} s | {size[1]}x{size[0]} | {ssim:.3f} | {100 * result.found:.1f} % "
                  f"| {axes} | {result.lips_r:.3f} | {result.brows_r:.3f} | {result.lips_gain:.2f} x "
                  f"| {result.brows_gain:.2f} x | {result.crosstalk_r:.3f} | {'noted' if raised else '-'} | {folded} "
                  f"| {'yes' if passed else 'no'} |")
            for key, value in (("ssim", ssim), ("pitch", abs(result.head_r["pitch"])),
                               ("yaw", abs(result.head_r["yaw"])), ("roll", abs(result.head_r["roll"])),
                               ("lips", result.lips_r), ("brows", result.brows_r), ("control", result.crosstalk_r),
                               ("lips read at", result.lips_gain), ("brows read at", result.brows_gain),
                               ("cells folded", folded)):
                summary.setdefault(key, []).append(value)
    print("\nmedian over people: " + ", ".join(f"{k} {np.median(v):.3f} (min {np.min(v):.3f})"
                                               for k, v in summary.items()))
    print(f"{measured - failures} of {measured} person-frames pass every mark; "
          f"{sum(all(v) for v in passes.values())} of {len(passes)} people on every frame of theirs ("
          + ", ".join(f"{name} {sum(v)} of {len(v)}" for name, v in passes.items()) + ")")
    return 0


if __name__ == "__main__":
    sys.exit(record("photo_loop", lambda: main(sys.argv[1:]),
                    lambda: [data_folder("talking-videos", needs="the talking-videos clips")]))
