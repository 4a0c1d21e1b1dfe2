"""The photo head's chin line when the jaw opens (part of ``make evaluate``).

A photo head's face is drawn over the person's grid (neck, hair, collar), which follows the face's skin near it
and fades out :data:`prosody.head.photo.SKIN_FOLLOW_CM` outside it. Where the fade is too steep for the grid's
cells, an opening jaw bends them, and the photo's chin line shows as a saw-tooth. The measure is
:func:`prosody.evaluation.head_loop.jaggedness` along the chin's outline (:func:`~prosody.evaluation.head_loop.
chin_arc`, where it is drawn in each frame): the grey levels a 4-pixel smoothing along it takes off, extra over
the same head at rest. Each condition opens the jaw, alone or with a turn (and a speech-like "ah" with a small
nod and turn), on one frame of each talking-head speaker (``videos_speakers.csv``; GRID's and the child's
clips left out). The fade shipped is set beside the one before (1.5 cm) on the same photos, paired by photo.

The fade was chosen looking at the frames of seed 0; the default seed (1) draws other frames.
``python -m experiments.chin_line [--seed 1]``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from experiments.common import data_folder, record
from experiments.expression_reading import fap_values, speakers
from experiments.photo_loop import grab_frame

#: The fade before, in cm.
BEFORE_CM = 1.5


def conditions() -> dict[str, dict[int, float]]:
    """Name -> FAP values (jaw in MNS, turns in FAP units)."""
    from prosody.fap.units import AU_PER_DEGREE

    nod, up, turn, roll = 9 * AU_PER_DEGREE, -9 * AU_PER_DEGREE, 14 * AU_PER_DEGREE, 7 * AU_PER_DEGREE
    return {"jaw 600 MNS": {3: 600}, "and a nod of 9 degrees": {3: 600, 48: nod},
            "and 9 degrees up": {3: 600, 48: up}, "and a turn of 14 degrees": {3: 600, 49: turn},
            "and a roll of 7 degrees": {3: 600, 50: roll},
            "an 'ah': jaw 750, nod 4, turn 5": {3: 750, 48: 4 * AU_PER_DEGREE, 49: 5 * AU_PER_DEGREE}}


def standard_error(values: np.ndarray) -> float:
    return float(values.std() / np.sqrt(len(values)))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)
    videos = data_folder("talking-videos", needs="the talking-videos clips")
    from prosody.errors import PhotoError
    from prosody.evaluation.head_loop import chin_arc, jaggedness
    from prosody.fap.table import N_FAPS
    from prosody.head import photo

    frames = {name: fap_values(faps) for name, faps in conditions().items()}
    shipped = photo.SKIN_FOLLOW_CM
    extra: dict[float, dict[str, list[float]]] = {fade: {} for fade in (BEFORE_CM, shipped)}
    skipped = []
    with tempfile.TemporaryDirectory() as folder:
        for index, (speaker, _, clip) in enumerate(speakers(videos)):
            picture = Path(folder) / f"{speaker}.png"
            grab_frame(clip, args.seed * 1000 + index + 77, picture)
            try:
                head = photo.photo_head(picture)
            except PhotoError as error:
                skipped.append(f"{speaker} ({str(error).split(': ', 1)[-1]})")
                continue
            arc = chin_arc(head)
            for fade in extra:
                photo.SKIN_FOLLOW_CM = fade
                try:
                    renderer = photo.PhotoRenderer(head)
                finally:
                    photo.SKIN_FOLLOW_CM = shipped
                rest = np.zeros(N_FAPS)
                at_rest = jaggedness(renderer.render(rest), renderer.pixels(rest)[arc])
                for name, values in frames.items():
                    seen = jaggedness(renderer.render(values), renderer.pixels(values)[arc])
                    extra[fade].setdefault(name, []).append(seen - at_rest)
    photos = len(next(iter(extra[shipped].values())))
    print(f"the chin line on {photos} photo heads (one frame per speaker, seed {args.seed}): jaggedness along the "
          f"chin, extra over rest (grey levels; mean ± standard error)")
    if skipped:
        print("not built: " + "; ".join(skipped))
    print(f"\n| condition | fade {BEFORE_CM:g} cm (before) | fade {shipped:g} cm (shipped) | paired difference "
          "| photos smoother |")
    print("|---|---|---|---|---|")
    for name in frames:
        before, now = np.array(extra[BEFORE_CM][name]), np.array(extra[shipped][name])
        difference = now - before
        print(f"| {name} | {before.mean():+.2f} ± {standard_error(before):.2f} | {now.mean():+.2f} ± "
              f"{standard_error(now):.2f} | {difference.mean():+.2f} ± {standard_error(difference):.2f} "
              f"| {int((difference < 0).sum())} of "
              f"{len(difference)} |")
    return 0


if __name__ == "__main__":
    sys.exit(record("chin_line", lambda: main(sys.argv[1:]),
                    lambda: [data_folder("talking-videos", needs="the talking-videos clips")]))
