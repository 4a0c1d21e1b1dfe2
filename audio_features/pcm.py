"""Audio that arrives as bytes: raw PCM, and WAV streams whose header may not know their length.

A WAV file written to a pipe by a recorder (``arecord``, ``sox``, ``ffmpeg -f wav -``) cannot go back to fill
in its sizes, so its RIFF and data sizes are 0 or 0xFFFFFFFF; :func:`read_wav_header` reads such a header
from a stream that cannot seek, and the data is then read to the end of the stream.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .audio import MAX_SAMPLE_RATE_HZ, MIN_SAMPLE_RATE_HZ
from .errors import AudioLoadError, ParameterError

#: Raw sample formats: name -> (bytes per sample, numpy type, full scale).
RAW_FORMATS = {
    "s16le": (2, "<i2", 32768.0),
    "s24le": (3, None, 8388608.0),
    "s32le": (4, "<i4", 2147483648.0),
    "f32le": (4, "<f4", 1.0),
    "f64le": (8, "<f8", 1.0),
    "u8": (1, "u1", 128.0),
}
#: Sizes a streaming writer puts in a WAV header when it does not know the length.
_UNKNOWN_SIZES = (0, 0xFFFFFFFF)
#: Largest header chunk (fmt, LIST, ...) read before the data.
_MAX_HEADER_CHUNK = 1 << 20


@dataclass(frozen=True)
class PcmFormat:
    """How the bytes of a stream hold samples.

    Parameters
    ----------
    sample_rate_hz : int in [8000, 768000]
    encoding : str
        A key of :data:`RAW_FORMATS` (s16le: 16-bit signed little-endian, ...).
    channels : int in [1, 64]
        Interleaved channels, averaged to mono.
    """

    sample_rate_hz: int
    encoding: str = "s16le"
    channels: int = 1

    def __post_init__(self) -> None:
        if self.encoding not in RAW_FORMATS:
            raise ParameterError(f"encoding {self.encoding!r} is not one of {', '.join(RAW_FORMATS)}")
        if isinstance(self.sample_rate_hz, bool) or not isinstance(self.sample_rate_hz, int) or not (
                MIN_SAMPLE_RATE_HZ <= self.sample_rate_hz <= MAX_SAMPLE_RATE_HZ):
            raise ParameterError(f"sample_rate_hz must be a whole number in [{MIN_SAMPLE_RATE_HZ}, "
                                 f"{MAX_SAMPLE_RATE_HZ}], got {self.sample_rate_hz!r}")
        if isinstance(self.channels, bool) or not isinstance(self.channels, int) or not 1 <= self.channels <= 64:
            raise ParameterError(f"channels must be a whole number in [1, 64], got {self.channels!r}")

    @property
    def frame_bytes(self) -> int:
        return RAW_FORMATS[self.encoding][0] * self.channels


def _container_of(head: bytes) -> str | None:
    """The name of a compressed or other container from its first bytes, if it is a known one."""
    if head[:3] == b"ID3" or (len(head) > 1 and head[0] == 0xFF and head[1] & 0xE0 == 0xE0):
        return "MP3"
    for magic, name in ((b"fLaC", "FLAC"), (b"OggS", "Ogg"), (b"FORM", "AIFF"), (b".snd", "AU"), (b"caff", "CAF")):
        if head.startswith(magic):
            return name
    if head[4:8] == b"ftyp":
        return "MP4/M4A"
    return None


class PcmDecoder:
    """Bytes in any piece sizes -> mono float samples (full scale +-1); a sample split between two pieces
    waits for the rest.

    Parameters
    ----------
    pcm : PcmFormat
        Rate, sample encoding and channels of the bytes.

    Examples
    --------
    >>> decoder = PcmDecoder(PcmFormat(16000))
    >>> decoder.decode(b"\\x00\\x40\\x00").tolist(), decoder.decode(b"\\xc0").tolist()
    ([0.5], [-0.5])
    """

    def __init__(self, pcm: PcmFormat) -> None:
        self.format = pcm
        self._pending = b""

    @property
    def pending_bytes(self) -> int:
        """Bytes of an incomplete sample frame still waiting for the rest."""
        return len(self._pending)

    def decode(self, data: bytes) -> np.ndarray:
        """Decode the next bytes of the stream; a partial frame at the end waits for the rest.

        Parameters
        ----------
        data : bytes
            The bytes that arrived, any number of them.

        Returns
        -------
        numpy.ndarray
            Mono float samples (channels mixed), full scale +-1.
        """
        data = self._pending + bytes(data)
        usable = len(data) - len(data) % self.format.frame_bytes
        self._pending = data[usable:]
        _, dtype, scale = RAW_FORMATS[self.format.encoding]
        body = data[:usable]
        values: np.ndarray
        if self.format.encoding == "s24le":
            raw = np.frombuffer(body, dtype=np.uint8).reshape(-1, 3).astype(np.int32)
            packed = raw[:, 0] | (raw[:, 1] << 8) | (raw[:, 2] << 16)
            values = np.where(packed >= 1 << 23, packed - (1 << 24), packed).astype(np.float64) / scale
        elif self.format.encoding == "u8":
            values = (np.frombuffer(body, dtype=dtype).astype(np.float64) - 128.0) / scale
        else:
            values = np.frombuffer(body, dtype=dtype).astype(np.float64) / scale
        values = values.reshape(-1, self.format.channels)
        mono = values[:, 0] if self.format.channels == 1 else values.mean(axis=1)
        finite = np.isfinite(mono)
        if not finite.all():
            raise AudioLoadError(f"sample value {float(mono[~finite][0])} is not finite; audio must have no NaN "
                                 "or infinity")
        return mono


def read_wav_header(read: Callable[[int], bytes], *, source: str = "<stream>") -> tuple[PcmFormat, int | None]:
    """Read a WAV header from a stream (``read(n)`` returns up to ``n`` bytes, ``b""`` at its end), up to
    the first byte of the samples.

    Parameters
    ----------
    read : callable
        ``read(n)`` returns up to ``n`` bytes of the stream.
    source : str
        How messages name the stream.

    Returns
    -------
    (PcmFormat, int or None)
        The sample format, and the number of data bytes the header promises (None when it says it does not
        know: read to the end of the stream).

    Raises
    ------
    AudioLoadError
        Not a RIFF/WAVE stream, a sample format other than integer PCM (8-32 bit) or IEEE float (32/64 bit),
        or a stream that ends inside the header.
    """

    def exactly(n: int, what: str) -> bytes:
        data = b""
        while len(data) < n:
            piece = read(n - len(data))
            if not piece:
                raise AudioLoadError(f"{source}: the stream ended inside the WAV header ({what})")
            data += piece
        return data

    riff = exactly(12, "RIFF header")
    if riff[:4] not in (b"RIFF", b"RF64") or riff[8:12] != b"WAVE":
        known = _container_of(riff)
        if known:
            raise AudioLoadError(f"{source}: {known} is read from a file, not from a stream: give the file itself, "
                                 "or pipe WAV or raw samples (e.g. ffmpeg -i IN -f wav -)")
        raise AudioLoadError(f"{source}: not a WAV stream (it starts with {riff[:4]!r}); pipe WAV, or raw samples "
                             "with --raw-rate HZ")
    pcm: PcmFormat | None = None
    while True:
        chunk_id, size = struct.unpack("<4sI", exactly(8, "chunk header"))
        if chunk_id == b"data":
            if pcm is None:
                raise AudioLoadError(f"{source}: the WAV data starts before its format (no 'fmt ' chunk)")
            return pcm, None if size in _UNKNOWN_SIZES or riff[:4] == b"RF64" else size
        if size > _MAX_HEADER_CHUNK:
            raise AudioLoadError(f"{source}: WAV chunk {chunk_id!r} of {size} bytes before the data; not a "
                                 "stream this reader takes")
        body = exactly(size + size % 2, f"{chunk_id.decode('latin-1')!r} chunk")[:size]
        if chunk_id == b"fmt ":
            if size < 16:
                raise AudioLoadError(f"{source}: WAV format chunk of {size} bytes (expected at least 16)")
            tag, channels, rate, _, _, bits = struct.unpack("<HHIIHH", body[:16])
            if tag == 0xFFFE and size >= 26:  # WAVE_FORMAT_EXTENSIBLE: the real tag opens the sub-format
                tag = struct.unpack("<H", body[24:26])[0]
            encodings = {(1, 8): "u8", (1, 16): "s16le", (1, 24): "s24le", (1, 32): "s32le", (3, 32): "f32le",
                         (3, 64): "f64le"}
            if (tag, bits) not in encodings:
                raise AudioLoadError(f"{source}: WAV sample format {tag} with {bits} bits is not read from a "
                                     "stream (use integer PCM of 8-32 bits or 32/64-bit float)")
            try:
                pcm = PcmFormat(int(rate), encodings[(tag, bits)], int(channels))
            except ParameterError as error:
                raise AudioLoadError(f"{source}: {error}") from None
