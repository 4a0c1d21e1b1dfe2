"""Tracking speed (part of ``make bench``): frames per second of ``prosody track``'s face tracking at 256x256
and at 1080p, beside the decoding alone of the same frames (measured side by side in this run).

The clips are 10 s of a talking-videos clip (DFRF_french, 512x512) scaled to each size with FFmpeg (H.264)
into a temporary folder. Aims: >= 60 frames/s at 256x256, >= 25 at 1080p.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

from experiments.common import data_folder

SOURCE = "DFRF_french.mp4"
SECONDS = 10
SIZES = {"256x256": (256, 256), "1080p": (1920, 1080)}
AIMS = {"256x256": 60.0, "1080p": 25.0}


def make_clip(source: Path, path: Path, width: int, height: int) -> Path:
    import imageio_ffmpeg

    # the square face video padded into a wide frame for 1080p, as a camera would film it
    scale = f"scale=-2:{height},pad={width}:{height}:(ow-iw)/2:0" if width != height else f"scale={width}:{height}"
    subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-v", "error", "-y", "-i", str(source), "-t", str(SECONDS),
                    "-vf", scale, "-c:v", "libx264", "-preset", "veryfast", "-crf", "18", "-c:a", "aac", str(path)],
                   check=True)
    return path


def decode_only(path: Path) -> tuple[int, float]:
    from prosody.tracking.video import iter_frames

    started = time.perf_counter()
    frames = sum(1 for _ in iter_frames(path))
    return frames, time.perf_counter() - started


def tracked(path: Path) -> tuple[int, float]:
    from prosody.tracking.face import FaceTracker
    from prosody.tracking.video import iter_frames

    with FaceTracker() as tracker:
        started = time.perf_counter()
        frames = 0
        for time_s, image in iter_frames(path):
            tracker.observe(image, time_s)
            frames += 1
        return frames, time.perf_counter() - started


def main() -> int:
    source = data_folder("talking-videos", needs="the talking-videos clips") / SOURCE
    print(f"tracking speed: {SECONDS} s of {SOURCE} at each size (decoding, scaling to at most 1280 px, face "
          "landmarks and blendshapes)")
    with tempfile.TemporaryDirectory() as folder:
        for label, (width, height) in SIZES.items():
            clip = make_clip(source, Path(folder) / f"{label}.mp4", width, height)
            decoded, decode_s = decode_only(clip)
            frames, track_s = tracked(clip)
            rate = frames / track_s
            print(f"  {label:<8} {rate:6.1f} frames/s tracked (aim >= {AIMS[label]:.0f}); decoding alone "
                  f"{decoded / decode_s:6.1f} frames/s; tracking / decoding time {track_s / decode_s:5.1f} x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
