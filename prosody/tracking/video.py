"""Reading talking-head videos: their frames, upright and timed, and their sound as 16 kHz mono.

PyAV (``pip install 'visual-prosody[track]'``) decodes with the FFmpeg it brings, so no system FFmpeg is
needed. One time base: 0 s is the first sample of the sound the video carries (after the encoder's priming,
which FFmpeg's decoders drop), and every frame is timed by its own timestamp on that base, so a variable
frame rate, a video that starts before or after its sound, and an audio track that starts late all come out
right. A video without sound is timed from its first frame; its sound may then be a WAV file given beside it.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import TrackingError

#: Sample rate of the sound written beside the tracked curves (the talking-heads convention).
TRACK_AUDIO_RATE_HZ = 16000
#: File name endings taken as videos when a folder is scanned.
VIDEO_EXTENSIONS = (".mp4", ".mov", ".m4v", ".mkv", ".webm", ".avi", ".mpg", ".mpeg", ".ts", ".mts", ".flv",
                    ".wmv", ".3gp")
#: Largest frame accepted (pixels): beyond 8K is a damaged or hostile header.
MAX_FRAME_PIXELS = 7680 * 4320
#: Frames wider or taller than this are scaled down before the face model sees them: its face detector
#: works on a 128-pixel image and its landmark model on a 256-pixel crop, so a face in a 1280-pixel frame
#: already has all the detail they use, and decoding into a smaller picture is what makes 1080p fast.
DEFAULT_MAX_SIDE_PX = 1280


def _import_av():
    try:
        import av
    except ImportError:
        raise TrackingError("reading videos needs PyAV: pip install 'visual-prosody[track]'") from None
    return av


@dataclass(frozen=True)
class VideoInfo:
    """What a video file holds.

    Attributes
    ----------
    path : str
    width_px, height_px : int
        The stored frame size (before rotation).
    rotation_deg : int
        Counter-clockwise rotation a player applies to show the frames upright (0, 90, 180 or 270).
    fps : float
        The stream's average frame rate (frames are timed by their own timestamps, not by this).
    duration_s : float
        Length of the video stream, in s.
    has_audio : bool
    video_start_s : float
        First frame's time on the video's own clock minus the first audio sample's, in s: positive when the
        picture starts after the sound. 0 without sound.
    """

    path: str
    width_px: int
    height_px: int
    rotation_deg: int
    fps: float
    duration_s: float
    has_audio: bool
    video_start_s: float


def _open(path: str | os.PathLike[str]):
    av = _import_av()
    name = str(path)
    if not Path(name).exists():
        raise TrackingError(f"{name}: no such file")
    if not Path(name).is_file():
        raise TrackingError(f"{name}: not a regular file")
    try:
        container = av.open(name, mode="r", metadata_errors="ignore")
    except (av.FFmpegError, UnicodeDecodeError, ValueError) as error:
        raise TrackingError(f"{name}: not a video that FFmpeg can read ({_reason(error)})") from None
    if not container.streams.video:
        container.close()
        raise TrackingError(f"{name}: holds no video stream")
    return container


def _reason(error: BaseException) -> str:
    """FFmpeg's own words for an error (PyAV's message adds an errno and the file name)."""
    words = getattr(error, "strerror", None)
    if isinstance(words, str) and words:
        return words
    text = " ".join(str(error).split())
    return text.split(": '", 1)[0] if text else type(error).__name__


def _stream_start_s(stream) -> float | None:
    if stream.start_time is None or stream.time_base is None:
        return None
    return float(stream.start_time * stream.time_base)


def _first_audio_time_s(container) -> float | None:
    """Time of the first decoded audio sample on the container's clock (None without a decodable one)."""
    av = _import_av()
    stream = container.streams.audio[0]
    try:
        for frame in container.decode(stream):
            if frame.samples and frame.time is not None:
                return float(frame.time)
    except av.FFmpegError:
        return None
    return _stream_start_s(stream)


def probe_video(path: str | os.PathLike[str]) -> VideoInfo:
    """Read a video's size, rotation, rate and the offset between its picture and its sound.

    Raises
    ------
    TrackingError
        No such file, not a video FFmpeg reads, no video stream, or a frame size beyond 8K.
    """
    av = _import_av()
    name = str(path)
    with _open(name) as container:
        stream = container.streams.video[0]
        width, height = int(stream.codec_context.width or 0), int(stream.codec_context.height or 0)
        if width * height > MAX_FRAME_PIXELS:
            raise TrackingError(f"{name}: frames of {width}x{height} pixels are beyond 8K; not a video this reads")
        rate = stream.average_rate or stream.guessed_rate or stream.base_rate
        fps = float(rate) if rate else math.nan
        if stream.duration is not None and stream.time_base is not None:
            duration = float(stream.duration * stream.time_base)
        elif container.duration is not None:
            duration = container.duration / av.time_base
        else:
            duration = math.nan
        rotation = 0
        video_start = None
        try:
            for frame in container.decode(stream):
                rotation = int(round(frame.rotation or 0)) % 360
                video_start = float(frame.time) if frame.time is not None else None
                width, height = frame.width, frame.height
                break
        except av.FFmpegError as error:
            raise TrackingError(f"{name}: its video cannot be decoded ({_reason(error)})") from None
        if video_start is None:
            raise TrackingError(f"{name}: its video stream has no frames")
        has_audio = bool(container.streams.audio)
        offset = 0.0
        if has_audio:
            container.seek(0)
            audio_start = _first_audio_time_s(container)
            if audio_start is None:
                has_audio = False
            else:
                offset = video_start - audio_start
    return VideoInfo(name, width, height, rotation, fps, duration, has_audio, offset)


def read_video_audio(path: str | os.PathLike[str], *,
                     sample_rate_hz: int = TRACK_AUDIO_RATE_HZ) -> Iterator[np.ndarray]:
    """The video's sound, mixed to mono and resampled, in blocks of float32 samples from its first sample.

    Memory stays bounded whatever the length: blocks come as FFmpeg decodes them.

    Raises
    ------
    TrackingError
        The video has no sound, or its sound cannot be decoded.
    """
    av = _import_av()
    name = str(path)
    with _open(name) as container:
        if not container.streams.audio:
            raise TrackingError(f"{name}: has no sound")
        stream = container.streams.audio[0]
        stream.thread_type = "AUTO"
        resampler = av.AudioResampler(format="flt", layout="mono", rate=sample_rate_hz)
        try:
            for frame in container.decode(stream):
                for out in resampler.resample(frame):
                    yield out.to_ndarray().reshape(-1)
            for out in resampler.resample(None):
                yield out.to_ndarray().reshape(-1)
        except av.FFmpegError as error:
            raise TrackingError(f"{name}: its sound cannot be decoded ({_reason(error)})") from None


def _upright(image: np.ndarray, rotation_deg: int) -> np.ndarray:
    """The frame as a player shows it: ``rotation_deg`` counter-clockwise (the display matrix's angle)."""
    turns = (rotation_deg // 90) % 4
    return np.ascontiguousarray(np.rot90(image, k=turns)) if turns else image


def _scaled_size(width: int, height: int, max_side_px: int | None) -> tuple[int, int]:
    if not max_side_px or max(width, height) <= max_side_px:
        return width, height
    scale = max_side_px / max(width, height)
    # even sizes: FFmpeg's RGB conversion of subsampled chroma wants them
    return max(2, int(round(width * scale / 2)) * 2), max(2, int(round(height * scale / 2)) * 2)


def iter_frames(path: str | os.PathLike[str], *, info: VideoInfo | None = None,
                max_side_px: int | None = DEFAULT_MAX_SIDE_PX) -> Iterator[tuple[float, np.ndarray]]:
    """``(time_s, rgb)`` for every frame, upright, timed on the sound's clock (see the module).

    Parameters
    ----------
    info : VideoInfo, optional
        From :func:`probe_video` (probed here when not given).
    max_side_px : int > 0 or None
        Frames larger than this on either side are scaled down (keeping their shape); None keeps them.

    Raises
    ------
    TrackingError
        The video cannot be decoded.
    """
    av = _import_av()
    info = info or probe_video(path)
    name = str(path)
    with _open(name) as container:
        stream = container.streams.video[0]
        stream.thread_type = "AUTO"
        origin = None
        last_time = -math.inf
        try:
            for frame in container.decode(stream):
                if frame.time is None:
                    continue
                if origin is None:
                    origin = float(frame.time) - info.video_start_s
                time_s = float(frame.time) - origin
                if time_s <= last_time:  # a repeated or out-of-order timestamp: keep the first
                    continue
                last_time = time_s
                width, height = _scaled_size(frame.width, frame.height, max_side_px)
                image = frame.to_ndarray(format="rgb24", width=width, height=height)
                rotation = int(round(frame.rotation or 0)) % 360
                yield time_s, _upright(image, rotation)
        except av.FFmpegError as error:
            raise TrackingError(f"{name}: its video cannot be decoded after {max(last_time, 0):.2f} s "
                                f"({_reason(error)})") from None
