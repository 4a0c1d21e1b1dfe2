"""Head rendering speed (part of ``make bench``): frames per second of the 3D head's CPU renderer at 640x480
and 1280x720, beside FFmpeg encoding the same frames to H.264 (``prosody preview``'s settings: libx264,
veryfast, CRF 20), measured side by side in this run on the same frames.

The motion is the sample recording's (``samples/arctic_a0009.wav``, all of the default stream's FAPs), looped
to :data:`FRAMES` frames. Aims: 60 frames/s at 640x480 on 2 cores, and the photo head (:mod:`prosody.head.photo`)
30 frames/s at 512x512; rendering within 4x of the encoding.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from prosody.evaluation.preview import find_ffmpeg, head_values
from prosody.head.render import HeadRenderer
from prosody.jobs.pipeline import convert

REPO = Path(__file__).resolve().parents[1]
FRAMES = 300
SIZES = {"640x480": (640, 480), "1280x720": (1280, 720)}
AIM_FPS = 60.0
AIM_RATIO = 4.0
#: The photo head: frames of 512 x 512 at >= 30 frames/s on 2 cores.
PHOTO_SIZE, AIM_PHOTO_FPS = 512, 30.0


def encode_fps(frames: list[np.ndarray], ffmpeg: str) -> float:
    height, width = frames[0].shape[:2]
    command = [ffmpeg, "-hide_banner", "-loglevel", "error", "-y", "-f", "rawvideo", "-pix_fmt", "rgb24",
               "-s", f"{width}x{height}", "-framerate", "30", "-i", "pipe:0", "-c:v", "libx264",
               "-preset", "veryfast", "-crf", "20", "-pix_fmt", "yuv420p", "-f", "mp4", "/dev/null"]
    start = time.perf_counter()
    process = subprocess.Popen(command, stdin=subprocess.PIPE)
    assert process.stdin is not None
    for frame in frames:
        process.stdin.write(frame.tobytes())
    process.stdin.close()
    if process.wait() != 0:
        raise RuntimeError("ffmpeg failed")
    return len(frames) / (time.perf_counter() - start)


def main() -> int:
    ffmpeg = find_ffmpeg()
    if ffmpeg is None:
        print("head bench: needs ffmpeg (pip install imageio-ffmpeg)")
        return 1
    stream = convert(REPO / "samples" / "arctic_a0009.wav", None)
    values = head_values(stream)
    rows = [values[k % len(values)] for k in range(FRAMES)]
    print(f"3D head rendering, {FRAMES} frames of the sample's motion (FAPs "
          f"{int(stream.mask.any(axis=0).sum())}), one process:")
    failed = False
    for name, (width, height) in SIZES.items():
        render_fps, encoding_fps = side_by_side(HeadRenderer(width, height), rows, ffmpeg)
        ratio = encoding_fps / render_fps
        print(f"  {name:>9}: render {render_fps:6.1f} frames/s   ffmpeg H.264 {encoding_fps:6.1f} frames/s   "
              f"render takes {ratio:4.2f} x the encoding (aim <= {AIM_RATIO:g} x)")
        failed |= ratio > AIM_RATIO
        if name == "640x480":
            met = "met" if render_fps >= AIM_FPS else "not met"
            print(f"             aim >= {AIM_FPS:g} frames/s at 640x480: {met}")
    failed |= photo_head_speed(rows, ffmpeg)
    return 1 if failed else 0


def side_by_side(renderer, rows: list[np.ndarray], ffmpeg: str) -> tuple[float, float]:
    """Frames per second of ``renderer`` over ``rows`` (compiled, or loaded from Numba's cache, before timing)
    and of FFmpeg encoding the frames it drew."""
    renderer.render(rows[0])
    start = time.perf_counter()
    frames = [renderer.render(row) for row in rows]
    return len(rows) / (time.perf_counter() - start), encode_fps(frames, ffmpeg)


def photo_head_speed(rows: list[np.ndarray], ffmpeg: str) -> bool:
    """The photo head at 512 x 512 beside FFmpeg's encoding of its frames; True where an aim is missed. The
    photo is a frame of the 3D head (a face the landmarker finds, no data needed); a real photo's head has
    about as many triangles (the person's grid is sized by the photo)."""
    try:
        from prosody.head.photo import PhotoRenderer, photo_head

        head = photo_head(HeadRenderer(PHOTO_SIZE, PHOTO_SIZE).render(np.zeros(68)), name="bench")
    except ImportError as error:
        print(f"  photo head: skipped ({error})")
        return False
    render_fps, encoding_fps = side_by_side(PhotoRenderer(head), rows, ffmpeg)
    ratio = encoding_fps / render_fps
    print(f"  photo head {PHOTO_SIZE}x{PHOTO_SIZE}: render {render_fps:6.1f} frames/s   ffmpeg H.264 "
          f"{encoding_fps:6.1f} frames/s   render takes {ratio:4.2f} x the encoding (aim <= {AIM_RATIO:g} x, "
          f">= {AIM_PHOTO_FPS:g} frames/s: {'met' if render_fps >= AIM_PHOTO_FPS else 'not met'})")
    return ratio > AIM_RATIO or render_fps < AIM_PHOTO_FPS


if __name__ == "__main__":
    sys.exit(main())
