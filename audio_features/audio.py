"""Loading speech audio: any file libsndfile reads, mixed to mono, checked before analysis."""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import AudioLoadError
from .inputs import check_input

#: File name endings taken as audio when a folder is scanned (training pairs, batches).
AUDIO_EXTENSIONS = (".wav", ".flac", ".ogg", ".oga", ".mp3", ".aif", ".aiff", ".aifc", ".au", ".caf", ".w64")
#: Lowest sample rate accepted (SPEC section 2: "any sample rate from 8 kHz up").
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
            # mix multichannel to mono: SPEC section 2
            samples = samples.mean(axis=1)
        if samples.ndim != 1:
            raise AudioLoadError(f"{self.source}: audio must be 1-D or (samples, channels), got {samples.shape!r}")
        check_samples(samples, source=self.source, sample_rate_hz=self.sample_rate_hz)
        object.__setattr__(self, "samples", samples)

    @property
    def duration_s(self) -> float:
        return self.samples.shape[0] / self.sample_rate_hz


def check_shape(n_samples: int, *, source: str, sample_rate_hz: float) -> None:
    """Raise :class:`AudioLoadError` for a recording with no samples or too low a sample rate."""
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
    """Raise :class:`AudioLoadError` for audio no analysis can use (empty, non-finite, too low a rate)."""
    check_shape(samples.shape[0], source=source, sample_rate_hz=sample_rate_hz)
    finite = np.isfinite(samples)
    if not finite.all():
        first = int(np.argmin(finite))
        raise AudioLoadError(
            f"{source}: sample {first} is {samples[first]!r}; audio must be finite (no NaN or infinity)"
        )


def check_readable(path: str | os.PathLike[str]) -> Path:
    """Return ``path`` as a Path if it names a readable, non-empty regular file, else raise AudioLoadError."""
    file = Path(path)
    try:
        size = check_input(file)
    except FileNotFoundError:
        raise AudioLoadError(f"{file}: no such file") from None
    except IsADirectoryError:
        raise AudioLoadError(f"{file}: is a directory, not an audio file") from None
    except OSError as error:
        raise AudioLoadError(f"{file}: cannot be read ({error.strerror or error})") from None
    if size == 0:
        raise AudioLoadError(f"{file}: the file is empty (0 bytes)")
    _check_riff_truncation(file)
    return file


def _check_riff_truncation(file: Path) -> None:
    """libsndfile reads a cut-off WAV without complaint; compare the data chunk's promise to the file."""
    size = file.stat().st_size
    with open(file, "rb") as handle:
        head = handle.read(12)
        if len(head) < 12 or head[:4] not in (b"RIFF", b"RIFX") or head[8:12] != b"WAVE":
            return
        endian = "<" if head[:4] == b"RIFF" else ">"
        offset = 12
        while offset + 8 <= size:
            handle.seek(offset)
            chunk_id, chunk_size = struct.unpack(endian + "4sI", handle.read(8))
            if chunk_id == b"data":
                available = size - offset - 8
                # 0 and 0xFFFFFFFF are the placeholders streaming writers leave: not a promise
                if chunk_size not in (0, 0xFFFFFFFF) and chunk_size > available:
                    raise AudioLoadError(
                        f"{file}: truncated WAV: the header promises {chunk_size} bytes of audio data "
                        f"but the file holds {available}"
                    )
                return
            offset += 8 + chunk_size + (chunk_size & 1)


def open_sound_file(path: str | os.PathLike[str]):
    """Open ``path`` with soundfile after the checks of :func:`check_readable`; errors become AudioLoadError."""
    import soundfile

    file = check_readable(path)
    try:
        # bytes, so that a file name that is not UTF-8 opens too (soundfile encodes str strictly)
        return soundfile.SoundFile(os.fsencode(file) if os.name != "nt" else str(file))
    except (soundfile.SoundFileError, RuntimeError) as error:
        reason = str(error).split(": ", 1)[-1] if ": " in str(error) else str(error)
        raise AudioLoadError(f"{file}: not an audio file libsndfile can read ({reason.strip()})") from None


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
            data = sound.read(dtype="float64", always_2d=True)
        except (soundfile.SoundFileError, RuntimeError) as error:
            raise AudioLoadError(decode_failure(path, sound.format, error)) from None
        if data.shape[0] < sound.frames and sound.format not in ESTIMATED_LENGTH_FORMATS:
            raise AudioLoadError(truncation(path, sound.format, sound.frames, data.shape[0]))
        rate = int(sound.samplerate)
    return Audio(data, rate, str(path))


def decode_failure(path: str | os.PathLike[str], container: str, error: BaseException) -> str:
    """The message for a decoder that gave up part-way: the file is cut off or damaged."""
    detail = str(error).split(": ", 1)[-1].strip()
    return f"{path}: truncated or damaged {container} file: the decoder stopped ({detail})"


def truncation(path: str | os.PathLike[str], container: str, promised: int, found: int) -> str:
    """The message for a file that holds fewer samples than its header promises."""
    return (f"{path}: truncated {container} file: the header promises {promised} samples but only {found} "
            "could be decoded")
