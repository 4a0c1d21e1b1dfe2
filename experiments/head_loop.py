"""The head's closed loop on a long clip (part of ``make evaluate``): 60 s of known motion rendered by
``prosody preview`` at 480 px and tracked back by ``prosody track``; prints the figures of
:mod:`prosody.evaluation.head_loop` and fails (exit 1) below its pass marks. Needs no shared data.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import soundfile

from experiments.common import record
from prosody.evaluation.head_loop import AMPLITUDES, PERIODS_S, known_motion, measure
from prosody.fap.fapfile import write_fap

SECONDS = 60.0


def main() -> int:
    stream = known_motion(SECONDS)
    with tempfile.TemporaryDirectory() as folder:
        work = Path(folder)
        write_fap(stream, work / "loop.fap")
        t = np.arange(int(SECONDS * 16000)) / 16000
        soundfile.write(work / "loop.wav", 0.1 * np.sin(2 * np.pi * 220 * t), 16000)
        timings = {}
        for name, command in (("render", ["preview", str(work / "loop.fap"), "--audio", str(work / "loop.wav"),
                                          "-o", str(work / "loop.mp4"), "--brow-scale", "1", "--no-strip", "-q"]),
                              ("track", ["track", str(work / "loop.mp4"), "-o", str(work / "tracked"), "-q"])):
            start = time.perf_counter()
            subprocess.run([sys.executable, "-m", "prosody", *command], check=True)
            timings[name] = time.perf_counter() - start
        result = measure(stream, work / "tracked" / "loop")
    print(f"head closed loop: {SECONDS:.0f} s at 30 fps, 480x480; motion "
          + ", ".join(f"{k} {AMPLITUDES[k]:g} / {PERIODS_S[k]:g} s" for k in AMPLITUDES)
          + " (deg, MNS, ENS / period)")
    print(f"  render {timings['render']:.1f} s, track {timings['track']:.1f} s")
    for line in result.lines():
        print("  " + line)
    return 0 if result.passed else 1


if __name__ == "__main__":
    sys.exit(record("head_loop", lambda: main(), lambda: []))
