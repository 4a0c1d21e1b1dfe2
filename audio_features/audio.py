"""Loading speech audio: any file libsndfile reads, mixed to mono, checked before analysis."""

from __future__ import annotations

import contextlib
import os
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import AudioLoadError
from .inputs import check_input, reading

#: File name endings taken as audio when a folder is scanned (training pairs, batches).
AUDIO_EXTENSIONS = (".wav", ".flac", ".ogg", ".oga", ".mp3", ".aif", ".aiff", ".aifc", ".au", ".caf", ".w64")
#: Lowest sample rate accepted: any sample rate from 8 kHz up.
MIN_SAMPLE_RATE_HZ = 8000
#: Highest sample rate accepted: above every rate recorders and interfaces use (768 kHz); a header that
#: claims more is damaged or hostile, and would make the analysis run for ever.
MAX_SAMPLE_RATE_HZ = 768000
#: Containers whose header gives only an estimate of the length (MP3 without an exact Xing/LAME frame
#: count): they are decoded to the end to learn it, and what is there is used.
ESTIMATED_LENGTH_FORMATS = frozenset({"MP3", "MPEG"})


# arrays inside: equality is identity (numpy's == is elementwise), so it stays hashable
@dataclass(frozen=True, eq=False)
class Audio:
    """Mono audio in memory.

    Parameters
    ----------
    samples : array of shape (n_samples,) or (n_samples, n_channels)
        The signal, full scale +-1 for floats (taken as pascals for the intensity scale); integer PCM
        (int16, int32, uint8) is scaled from its type's full range. Channels are averaged.
    sample_rate_hz : int >= 8000
        Samples per second.
    source : str
        Where the audio came from (a path, or a description for synthetic signals).
    """

    samples: np.ndarray
    sample_rate_hz: int
    source: str = "<memory>"

    def __post_init__(self) -> None:
        raw = np.asarray(self.samples)
        if raw.dtype.kind in "iu":
            # integer PCM (int16 from a WAV reader, ...): full scale is the type's range, not 1
            info = np.iinfo(raw.dtype)
            samples = (raw.astype(np.float64) - (info.max + info.min + 1) / 2) / ((info.max - info.min + 1) / 2)
        elif raw.dtype.kind in "fb":
            samples = raw.astype(np.float64)
        else:
            raise AudioLoadError(f"{self.source}: samples must be numbers, got an array of {raw.dtype}")
        if samples.ndim == 2 and samples.shape[0] < samples.shape[1] and samples.shape[0] <= 8:
            raise AudioLoadError(
                f"{self.source}: samples of shape {samples.shape!r} look channels-first; pass "
                "(samples, channels), e.g. samples.T"
            )
        if samples.ndim == 2:
            # mix multichannel to mono, as the analysis of one voice wants
            samples = samples.mean(axis=1)
        if samples.ndim != 1:
            raise AudioLoadError(f"{self.source}: audio must be 1-D or (samples, channels), got {samples.shape!r}")
        check_samples(samples, source=self.source, sample_rate_hz=self.sample_rate_hz)
        object.__setattr__(self, "samples", samples)

    @property
    def duration_s(self) -> float:
        return self.samples.shape[0] / self.sample_rate_hz


def check_shape(n_samples: int, *, source: str, sample_rate_hz: float) -> None:
    """Raise :class:`AudioLoadError` for a recording with no samples or too low a sample rate.

    Parameters
    ----------
    n_samples : int
        Samples per channel.
    source : str
        How the message names the recording.
    sample_rate_hz : float
        Its rate.
    """
    if not sample_rate_hz >= MIN_SAMPLE_RATE_HZ:
        raise AudioLoadError(
            f"{source}: sample rate {sample_rate_hz!r} Hz is below the supported minimum of "
            f"{MIN_SAMPLE_RATE_HZ} Hz; resample the file first"
        )
    if sample_rate_hz > MAX_SAMPLE_RATE_HZ:
        raise AudioLoadError(
            f"{source}: the header claims a sample rate of {sample_rate_hz!r} Hz, above any recording's "
            f"({MAX_SAMPLE_RATE_HZ} Hz at most): the file is damaged or not a recording"
        )
    if n_samples == 0:
        raise AudioLoadError(f"{source}: the recording has no samples (zero length)")


def check_samples(samples: np.ndarray, *, source: str, sample_rate_hz: float) -> None:
    """Raise :class:`AudioLoadError` for audio no analysis can use (empty, non-finite, too low a rate).

    Parameters
    ----------
    samples : numpy.ndarray
        The samples, (n,) or (n, channels).
    source : str
        How the message names the recording.
    sample_rate_hz : float
        Its rate.
    """
    check_shape(samples.shape[0], source=source, sample_rate_hz=sample_rate_hz)
    finite = np.isfinite(samples)
    if not finite.all():
        first = int(np.argmin(finite))
        raise AudioLoadError(
            f"{source}: sample {first} is {samples[first]!r}; audio must be finite (no NaN or infinity)"
        )


def check_readable(path: str | os.PathLike[str]) -> Path:
    """Return ``path`` as a Path if it names a readable, non-empty regular file, else raise AudioLoadError.

    Parameters
    ----------
    path : str or path-like
        The file.

    Returns
    -------
    pathlib.Path
    """
    file = Path(path)
    with reading(file, AudioLoadError, wanted="audio file"):
        size = check_input(file)
    if size == 0:
        raise AudioLoadError(f"{file}: the file is empty (0 bytes)")
    _check_container_truncation(file)
    return file


#: The GUIDs of Sony Wave64 that begin with these bytes (the rest of each GUID is fixed).
_W64_RIFF, _W64_DATA = b"riff", b"data"


def _truncated(file: Path, container: str, promised: int, available: int) -> AudioLoadError:
    return AudioLoadError(f"{file}: truncated {container}: the header promises {promised} bytes of audio data "
                          f"but the file holds {available}")


def _check_container_truncation(file: Path) -> None:
    """libsndfile reads a cut-off file of most containers without complaint, as if it were shorter: compare
    what each container's header promises with what the file holds (WAV, RF64, Wave64, AIFF, AU, Ogg, and MP3
    with a Xing, Info or VBRI tag)."""
    size = file.stat().st_size
    with open(file, "rb") as handle:
        head = handle.read(40)
        if head[:4] in (b"RIFF", b"RIFX", b"RF64") and head[8:12] == b"WAVE":
            _check_riff(handle, file, size, big_endian=head[:4] == b"RIFX", rf64=head[:4] == b"RF64")
        elif head[:4] == b"FORM" and head[8:12] in (b"AIFF", b"AIFC"):
            _check_chunks(handle, file, size, container="AIFF", start=12, header=">4sI", data=b"SSND")
        elif head[:4] == b".snd" and len(head) >= 12:
            offset, length = struct.unpack(">II", head[4:12])
            # 0xFFFFFFFF: the length was unknown when written (a stream): not a promise
            if length != 0xFFFFFFFF and offset + length > size:
                raise _truncated(file, "AU file", length, max(0, size - offset))
        elif head[:4] == _W64_RIFF and head[24:28] == b"wave":
            _check_w64(handle, file, size)
        elif head[:4] == b"OggS":
            _check_ogg_end(handle, file, size)
        elif head[:3] == b"ID3" or (len(head) >= 2 and head[0] == 0xFF and head[1] & 0xE0 == 0xE0):
            _check_mp3(handle, file, size)


def _check_mp3(handle, file: Path, size: int) -> None:
    """An MP3 whose first frame carries a Xing/Info (LAME, FFmpeg) or VBRI (Fraunhofer) tag says its stream's
    length in bytes: a file cut short holds fewer (the decoder itself only notes it on standard error)."""
    handle.seek(0)
    head = handle.read(10)
    start = 0
    if head[:3] == b"ID3" and len(head) == 10:  # an ID3v2 tag first: its size in four 7-bit bytes
        start = 10 + ((head[6] & 0x7F) << 21 | (head[7] & 0x7F) << 14 | (head[8] & 0x7F) << 7 | head[9] & 0x7F)
        start += 10 if head[5] & 0x10 else 0  # a footer
    handle.seek(start)
    frame = handle.read(2048)
    if len(frame) < 4 or frame[0] != 0xFF or frame[1] & 0xE0 != 0xE0:
        return
    promised = None
    for tag in (b"Xing", b"Info"):
        at = frame.find(tag, 4, 64)
        if at >= 0 and at + 8 <= len(frame):
            flags = struct.unpack(">I", frame[at + 4:at + 8])[0]
            fields = at + 8 + (4 if flags & 1 else 0)  # the frame count comes before the byte count
            if flags & 2 and fields + 4 <= len(frame):
                promised = struct.unpack(">I", frame[fields:fields + 4])[0]
            break
    else:
        at = frame.find(b"VBRI", 4, 64)
        if at >= 0 and at + 14 <= len(frame):
            promised = struct.unpack(">I", frame[at + 10:at + 14])[0]
    if not promised:
        return
    handle.seek(max(size - 128, 0))
    available = size - start - (128 if handle.read(3) == b"TAG" else 0)  # an ID3v1 tag last
    if available < promised * 0.99:  # the tag's count is rounded by some encoders: 1 % is tolerated
        raise _truncated(file, "MP3 file", promised, available)


def _check_riff(handle, file: Path, size: int, *, big_endian: bool, rf64: bool) -> None:
    endian = ">" if big_endian else "<"
    data_size_64 = None
    offset = 12
    while offset + 8 <= size:
        handle.seek(offset)
        chunk_id, chunk_size = struct.unpack(endian + "4sI", handle.read(8))
        if chunk_id == b"ds64" and rf64:
            fields = handle.read(24)
            if len(fields) == 24:
                _, data_size_64, _ = struct.unpack("<QQQ", fields)
        elif chunk_id == b"fmt ":
            _check_pcm_layout(handle.read(16), file, endian)
        elif chunk_id == b"data":
            promised = data_size_64 if (rf64 and chunk_size == 0xFFFFFFFF) else chunk_size
            available = size - offset - 8
            # 0 and 0xFFFFFFFF are the placeholders streaming writers leave: not a promise
            if promised is not None and promised not in (0, 0xFFFFFFFF) and promised > available:
                raise _truncated(file, "RF64 file" if rf64 else "WAV", promised, available)
            return
        offset += 8 + chunk_size + (chunk_size & 1)


def _check_pcm_layout(fields: bytes, file: Path, endian: str) -> None:
    """Integer PCM whose bits per sample do not fill its frames (a 7-bit header on 16-bit frames) is read by
    libsndfile from the bits, at the wrong length: refuse a header that contradicts itself."""
    if len(fields) < 16:
        return
    tag, channels, _, _, block_align, bits = struct.unpack(endian + "HHIIHH", fields)
    if tag == 1 and channels and bits and block_align != channels * ((bits + 7) // 8):
        raise AudioLoadError(f"{file}: damaged WAV header: {channels} channel(s) of {bits}-bit samples take "
                             f"{channels * ((bits + 7) // 8)} bytes per frame, but the header says {block_align}")


def _check_chunks(handle, file: Path, size: int, *, container: str, start: int, header: str, data: bytes) -> None:
    offset = start
    while offset + 8 <= size:
        handle.seek(offset)
        chunk_id, chunk_size = struct.unpack(header, handle.read(8))
        if chunk_id == data:
            available = size - offset - 8
            if chunk_size > available:
                raise _truncated(file, f"{container} file", chunk_size, available)
            return
        offset += 8 + chunk_size + (chunk_size & 1)


def _check_w64(handle, file: Path, size: int) -> None:
    offset = 40  # riff GUID, 64-bit size, wave GUID
    while offset + 24 <= size:
        handle.seek(offset)
        guid, chunk_size = struct.unpack("<16sQ", handle.read(24))  # the size counts the 24-byte header
        if guid[:4] == _W64_DATA:
            available = size - offset - 24
            if chunk_size - 24 > available:
                raise _truncated(file, "Wave64 file", chunk_size - 24, available)
            return
        if chunk_size < 24:
            return  # damaged beyond reading: libsndfile will say so
        offset += (chunk_size + 7) // 8 * 8


def _check_ogg_end(handle, file: Path, size: int) -> None:
    """An Ogg stream ends with a page marked end-of-stream; a cut-off file's last page is not."""
    tail_start = max(0, size - (1 << 16))  # a page is at most 65,307 bytes
    handle.seek(tail_start)
    tail = handle.read()
    last = tail.rfind(b"OggS")
    # header: capture pattern, version, header type (0x04: end of stream), ...; 27 bytes and the segment table
    if last < 0 or last + 27 > len(tail):
        raise AudioLoadError(f"{file}: truncated Ogg file: no complete page at its end")
    n_segments = tail[last + 26]
    body = sum(tail[last + 27:last + 27 + n_segments])
    if not tail[last + 5] & 0x04 or last + 27 + n_segments + body > len(tail):
        raise AudioLoadError(f"{file}: truncated Ogg file: its last page does not end the stream (the file was "
                             "cut off)")


#: Endings of files whose sound libsndfile does not read (AAC, ALAC, Opus in MP4, QuickTime, Matroska, WMA):
#: their sound is decoded by FFmpeg where one is found, else the refusal says how to convert them.
FFMPEG_ONLY_ENDINGS = (".m4a", ".mp4", ".aac", ".mov", ".mkv", ".webm", ".wma", ".3gp", ".m4v")


def find_ffmpeg() -> str | None:
    """An FFmpeg executable: ``ffmpeg`` on PATH, else the one of the ``imageio-ffmpeg`` package.

    Returns
    -------
    str or None
        Its path; None where there is neither.
    """
    import shutil

    found = shutil.which("ffmpeg")
    if found:
        return found
    try:
        import imageio_ffmpeg
    except ImportError:
        return None
    try:
        return str(imageio_ffmpeg.get_ffmpeg_exe())
    except RuntimeError:
        return None


def _decoded_by_ffmpeg(file: Path, ffmpeg: str):
    """The sound of ``file`` decoded by FFmpeg into 32-bit float WAV, open as a SoundFile (the temporary file is
    unlinked once open: it goes when the SoundFile is closed)."""
    import subprocess
    import tempfile

    import soundfile

    handle, temporary = tempfile.mkstemp(prefix="prosody-sound-", suffix=".wav")
    os.close(handle)
    try:
        done = subprocess.run([ffmpeg, "-nostdin", "-hide_banner", "-loglevel", "error", "-y", "-i", os.fspath(file),
                               "-vn", "-map", "0:a:0", "-acodec", "pcm_f32le", "-f", "wav", temporary],
                              capture_output=True, text=True, errors="replace")
        if done.returncode != 0:
            said = (done.stderr.strip().splitlines() or ["no sound"])[-1][:200]
            raise AudioLoadError(f"{file}: FFmpeg could not decode its sound ({said})")
        return soundfile.SoundFile(temporary)
    except (soundfile.SoundFileError, RuntimeError) as error:
        raise AudioLoadError(f"{file}: FFmpeg's decoding of its sound is not readable ({error})") from None
    finally:
        with contextlib.suppress(OSError):
            os.unlink(temporary)


def open_sound_file(path: str | os.PathLike[str]):
    """Open ``path`` with soundfile after the checks of :func:`check_readable`; errors become AudioLoadError.
    The sound of an MP4, M4A, MOV, MKV or WebM file (which libsndfile does not read) is decoded by FFmpeg where
    one is found (:func:`find_ffmpeg`).

    Parameters
    ----------
    path : str or path-like
        The audio file.

    Returns
    -------
    soundfile.SoundFile
        Open for reading; the caller closes it.
    """
    import soundfile

    file = check_readable(path)
    try:
        # bytes, so that a file name that is not UTF-8 opens too (soundfile encodes str strictly)
        return soundfile.SoundFile(os.fsencode(file) if os.name != "nt" else str(file))
    except (soundfile.SoundFileError, RuntimeError) as error:
        reason = str(error).split(": ", 1)[-1] if ": " in str(error) else str(error)
        hint = ""
        if Path(file).suffix.lower() in FFMPEG_ONLY_ENDINGS:  # AAC and the like in MP4 containers
            ffmpeg = find_ffmpeg()
            if ffmpeg is not None:
                return _decoded_by_ffmpeg(Path(file), ffmpeg)
            wav = Path(file).with_suffix(".wav").name
            hint = (f"; its sound is read through FFmpeg, which is not here (pip install imageio-ffmpeg), or can be "
                    f"converted first: ffmpeg -i {Path(file).name} -ac 1 {wav}")
        raise AudioLoadError(f"{file}: not an audio file libsndfile can read ({reason.strip()}){hint}") from None


#: PCM subtypes read as integers and scaled to +-1 here, by exactly libsndfile's factor (a power of two, so the
#: numbers are the same as its float64 reading): subtype -> (dtype read, divisor).
INTEGER_SCALES = {"PCM_16": ("int16", 1 << 15), "PCM_24": ("int32", 1 << 31), "PCM_32": ("int32", 1 << 31)}


def read_whole(sound) -> np.ndarray:
    """Every remaining frame of an open SoundFile as float64 (frames, channels); in blocks where libsndfile
    cannot seek (GSM 6.10 in WAV), since it then cannot tell how many frames are left.

    Parameters
    ----------
    sound : soundfile.SoundFile
        An open file.

    Returns
    -------
    numpy.ndarray
        (frames, channels), float64.
    """
    if sound.seekable():
        scale = INTEGER_SCALES.get(sound.subtype)
        if scale is not None:  # integers read as they are and scaled here: 3x quicker than libsndfile's doubles
            kind, divisor = scale
            return sound.read(dtype=kind, always_2d=True) * (1.0 / divisor)
        return sound.read(dtype="float64", always_2d=True)
    blocks = list(read_blocks(sound, 1 << 16))
    return np.concatenate(blocks) if blocks else np.zeros((0, sound.channels))


def read_blocks(sound, block_frames: int) -> Iterator[np.ndarray]:
    """The remaining frames of an open SoundFile in float64 blocks of ``block_frames`` (the last shorter),
    by explicit counts, which every codec allows (SoundFile.blocks needs seeking where none is given).

    Parameters
    ----------
    sound : soundfile.SoundFile
        An open file.
    block_frames : int
        Frames per block.

    Yields
    ------
    numpy.ndarray
        (frames, channels), float64.
    """
    while True:
        block = sound.read(frames=block_frames, dtype="float64", always_2d=True)
        if block.shape[0]:
            yield block
        if block.shape[0] < block_frames:
            return


def file_blocks(path: str | os.PathLike[str], *, seconds_per_block: float = 10.0) -> tuple[int, Iterator[np.ndarray]]:
    """``(sample rate, blocks)`` of a file read ``seconds_per_block`` at a time, mixed to mono (float64): bounded memory
    for recordings of any length. The file is checked as :func:`load_audio` checks it.

    Parameters
    ----------
    path : str or path-like
        The audio file.
    seconds_per_block : float
        Length of each block, in s.

    Returns
    -------
    sample_rate_hz : int
    blocks : iterator of numpy.ndarray
        Mono float64 blocks, in order.
    """
    sound = open_sound_file(path)
    check_shape(max(sound.frames, 1), source=str(path), sample_rate_hz=sound.samplerate)
    rate = int(sound.samplerate)

    def blocks() -> Iterator[np.ndarray]:
        import soundfile

        with sound:
            try:
                for block in read_blocks(sound, max(1, int(seconds_per_block * rate))):
                    mono = block[:, 0] if block.shape[1] == 1 else block.mean(axis=1)
                    if not np.isfinite(mono).all():
                        raise AudioLoadError(f"{path}: a sample is not finite; audio must have no NaN or infinity")
                    yield mono
            except (soundfile.SoundFileError, RuntimeError) as error:
                raise AudioLoadError(decode_failure(path, sound.format, error)) from None

    return rate, blocks()


def load_audio(path: str | os.PathLike[str]) -> Audio:
    """Read an audio file into memory as mono float64.

    Parameters
    ----------
    path : str or path-like
        Any file libsndfile reads: WAV (8/16/24/32-bit integer and float), FLAC, OGG, MP3, ...

    Returns
    -------
    Audio
        Mono samples (channels averaged), their sample rate and the path.

    Raises
    ------
    AudioLoadError
        For a missing, empty, truncated or unreadable file, a zero-length recording, a sample rate below
        8 kHz, or NaN/infinite samples.

    Examples
    --------
    >>> import numpy as np, soundfile, tempfile, os
    >>> path = os.path.join(tempfile.mkdtemp(), "tone.wav")
    >>> soundfile.write(path, 0.5 * np.sin(2 * np.pi * 200 * np.arange(8000) / 16000), 16000)
    >>> load_audio(path).duration_s
    0.5
    """
    import soundfile

    with open_sound_file(path) as sound:
        check_shape(max(sound.frames, 1), source=str(path), sample_rate_hz=sound.samplerate)
        try:
            data = read_whole(sound)
        except (soundfile.SoundFileError, RuntimeError) as error:
            raise AudioLoadError(decode_failure(path, sound.format, error)) from None
        if data.shape[0] < sound.frames and sound.format not in ESTIMATED_LENGTH_FORMATS:
            raise AudioLoadError(truncation(path, sound.format, sound.frames, data.shape[0]))
        rate = int(sound.samplerate)
    return Audio(data, rate, str(path))


def decode_failure(path: str | os.PathLike[str], container: str, error: BaseException) -> str:
    """The message for a decoder that gave up part-way: the file is cut off or damaged.

    Parameters
    ----------
    path : str or path-like
        The file.
    container : str
        Its format, as the message says it.
    error : BaseException
        What the decoder raised.

    Returns
    -------
    str
    """
    detail = str(error).split(": ", 1)[-1].strip()
    return f"{path}: truncated or damaged {container} file: the decoder stopped ({detail})"


def truncation(path: str | os.PathLike[str], container: str, promised: int, found: int) -> str:
    """The message for a file that holds fewer samples than its header promises.

    Parameters
    ----------
    path : str or path-like
        The file.
    container : str
        Its format, as the message says it.
    promised, found : int
        Samples the header promises, and those the file holds.

    Returns
    -------
    str
    """
    return (f"{path}: truncated {container} file: the header promises {promised} samples but only {found} "
            "could be decoded")
