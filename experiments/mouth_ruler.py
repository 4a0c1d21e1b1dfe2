"""What the face tracker reads of the 3D head's drawn mouth (part of ``make evaluate``; needs no shared data).

Held inner-lip openings (0 to 800 MNS, each for 20 frames, up and back down, the lips' own geometry of
``prosody.motion.face.lips.shape_faps``) are drawn by ``prosody preview`` at 480 px and tracked back by ``prosody
track``; beside each drawn opening, the mesh's own gap between the inner-lip midpoints (landmarks 13 and 14, in
MNS of the head) and the tracked opening converted to MNS as people's are (``MNS_PER_EYE_WIDTH``). A linear
ruler would read each opening times the head's MNS over 0.22 of its outer eye-corner distance. This is the
ruler that ``experiments/likeness.py`` reads our mouth with: where it is not linear, render and tracker change
the lips' r against people.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from experiments.common import record
from prosody.fap.fapfile import write_fap
from prosody.fap.recorded import read_mouth_csv
from prosody.fap.stream import FapStream
from prosody.head.rig import head_rig
from prosody.motion.face.lips import MNS_PER_EYE_WIDTH, VISEME_FAP, MouthShape, inner_opening, shape_faps

FPS = 30.0
LEVELS_MNS = (0.0, 50.0, 100.0, 150.0, 200.0, 300.0, 400.0, 500.0, 600.0, 800.0)
HOLD_FRAMES = 20
#: Frames left out at each end of a held opening (the tracker's smoothing and the change itself).
SETTLE_FRAMES = 5


def held_openings() -> np.ndarray:
    """The drawn inner-lip opening of every frame: each level held, up and then back down."""
    up = np.repeat(np.asarray(LEVELS_MNS), HOLD_FRAMES)
    return np.concatenate([up, up[::-1]])


def mesh_gap(opening_mns: float) -> float:
    """The head mesh's gap between the inner-lip midpoints at this drawn opening, in the head's MNS units."""
    rig = head_rig()
    faps = shape_faps(MouthShape(np.array([opening_mns]), np.zeros(1), np.zeros(1), np.zeros(1, int)))
    values = np.zeros(68)
    for fap, curve in faps.items():
        if fap != VISEME_FAP:
            values[fap - 1] = curve[0]
    rest, posed = rig.deform(np.zeros(68)), rig.deform(values)
    gap = (posed[13, 1] - posed[14, 1]) - (rest[13, 1] - rest[14, 1])
    return float(gap / rig.mesh.units.mns0 * 1024)


def main() -> None:
    opening = held_openings()
    n = opening.size
    faps = shape_faps(MouthShape(opening, np.zeros(n), np.zeros(n), np.zeros(n, int)))
    stream = FapStream.from_curves({fap: curve for fap, curve in faps.items() if fap != VISEME_FAP}, fps=FPS)
    assert np.allclose(inner_opening(faps), opening)
    mesh = head_rig().mesh
    eye_width = float(np.linalg.norm(mesh.vertices[33] - mesh.vertices[263]))
    linear = mesh.units.mns0 / (MNS_PER_EYE_WIDTH * eye_width)
    with tempfile.TemporaryDirectory() as folder:
        work = Path(folder)
        write_fap(stream, work / "ruler.fap")
        for command in (["preview", str(work / "ruler.fap"), "-o", str(work / "ruler.mp4"), "--brow-scale", "1",
                         "--no-strip", "-q"], ["track", str(work / "ruler.mp4"), "-o", str(work / "tracked"), "-q"]):
            subprocess.run([sys.executable, "-m", "prosody", *command], check=True)
        tracked = read_mouth_csv(work / "tracked" / "ruler.mouth.csv").lip_opening / MNS_PER_EYE_WIDTH * 1024
    print(f"the 3D head's drawn mouth read back by the face tracker (480 px, {HOLD_FRAMES} frames a level, up and "
          f"down); a linear ruler would read x{linear:.2f} (the head's MNS is {mesh.units.mns0 / eye_width:.3f} of "
          f"its outer eye-corner distance, people's are converted at {MNS_PER_EYE_WIDTH})\n")
    print("| drawn opening (MNS) | the mesh's inner-lip gap (MNS) | read by the tracker (MNS, median) | read / drawn |")
    print("|---|---|---|---|")
    for k, level in enumerate(LEVELS_MNS):
        up = tracked[k * HOLD_FRAMES + SETTLE_FRAMES:(k + 1) * HOLD_FRAMES - SETTLE_FRAMES]
        down = tracked[n - (k + 1) * HOLD_FRAMES + SETTLE_FRAMES:n - k * HOLD_FRAMES - SETTLE_FRAMES]
        read = float(np.nanmedian(np.concatenate([up, down])))
        ratio = f"{read / level:.2f}" if level else "-"
        print(f"| {level:.0f} | {mesh_gap(level):.0f} | {read:.0f} | {ratio} |")


if __name__ == "__main__":
    sys.exit(record("mouth_ruler", main, lambda: []))
