"""Phones of speech with their times, by PocketSphinx (CMU Sphinx) and the US English model its wheel ships.

Two ways, as lip-sync tools offer them:

- **phone loop** (no transcript): every phone the acoustic model hears, constrained only by a phone
  bigram model (``en-us-phone.lm.bin``). Works on any speech, English or not, at the cost of more errors;
- **alignment** (a transcript): the words are looked up in the CMU pronouncing dictionary and their phones
  aligned to the audio (Viterbi forced alignment, then a second pass for phone durations). Words the
  dictionary does not know are left out of the alignment (a :class:`TranscriptWarning` names them); when
  the text does not fit the audio at all, the phone loop is used instead, with a warning.

Phones are ARPAbet symbols without stress (``AA``, ``P``, ...) plus ``SIL`` for silence and noise.
Everything runs on the CPU from files inside the ``pocketsphinx`` package: nothing is downloaded.
"""

from __future__ import annotations

import os
import re
import warnings
from dataclasses import dataclass

import numpy as np

from .audio import Audio
from .errors import AudioFeaturesError, ParameterError

#: Sample rate of the acoustic model, Hz.
MODEL_RATE_HZ = 16000
#: The decoder's frame rate (10 ms frames).
DECODER_FPS = 100
#: Audio decoded as one utterance at the most, in s; longer recordings are cut at their quietest 10 ms
#: within the last 5 s before the limit, so memory stays bounded and cuts fall in pauses.
MAX_UTTERANCE_S = 30.0
#: Recordings of at least twice this many utterances are decoded on several cores (one process each).
PARALLEL_UTTERANCES = 2
#: Phone-loop decoder settings: language weight and phone insertion penalty. The weight is chosen by how well
#: the lips made from the phones follow people's mouths, each speaker held out (``experiments/phone_loop_weight.py``,
#: 35 speakers: the lips' opening r 0.413 against 0.378 at the weight before, 2, and 0.312 at PocketSphinx's
#: default, 6.5); the penalty made no difference there (0.1 to 1).
PHONE_LOOP_SETTINGS = {"lw": 0.75, "pip": 0.3}
#: Least fraction of a transcript's aligned phones that the phone loop must also hear for the alignment to be
#: used: on CMU ARCTIC speech the right text scores 0.55-0.6 and on espeak-ng's synthetic speech 0.31;
#: unrelated text 0.06-0.17, when it can be aligned at all.
MIN_AGREEMENT = 0.25
#: A phone whose loudest 10 ms is below this level (dBFS), or this far below the recording's loud level (its
#: 95th percentile), is silence.
QUIET_DBFS, QUIET_BELOW_LOUD_DB = -60.0, 40.0
#: ARPAbet phones of the model (stress removed), with SIL for silence and fillers.
PHONES = ("AA", "AE", "AH", "AO", "AW", "AY", "B", "CH", "D", "DH", "EH", "ER", "EY", "F", "G", "HH", "IH", "IY",
          "JH", "K", "L", "M", "N", "NG", "OW", "OY", "P", "R", "S", "SH", "SIL", "T", "TH", "UH", "UW", "V", "W",
          "Y", "Z", "ZH")


class TranscriptWarning(UserWarning):
    """A transcript was used in part (unknown words) or not at all (it does not fit the audio)."""


class PhoneRecognitionError(AudioFeaturesError, RuntimeError):
    """PocketSphinx is missing or failed."""


@dataclass(frozen=True)
class Phone:
    """One phone: ARPAbet label (or SIL) from ``start_s`` to ``end_s``.

    Attributes
    ----------
    label : str
        ARPAbet phone, or ``SIL``.
    start_s, end_s : float
        Its span on the recording, in s.
    """

    label: str
    start_s: float
    end_s: float

    @property
    def centre_s(self) -> float:
        return 0.5 * (self.start_s + self.end_s)


def _model_dir() -> str:
    try:
        from pocketsphinx import get_model_path
    except ImportError:
        raise PhoneRecognitionError("phones need PocketSphinx: pip install pocketsphinx") from None
    return os.path.join(get_model_path(), "en-us")


def _decoder(**settings):
    from pocketsphinx import Decoder

    return Decoder(loglevel="FATAL", samprate=MODEL_RATE_HZ, **settings)


def _resampled(samples: np.ndarray, rate: int) -> np.ndarray:
    """Mono 16-bit samples at 16 kHz, as the acoustic model was trained on."""
    if rate != MODEL_RATE_HZ:
        from math import gcd

        from scipy.signal import resample_poly

        common = gcd(rate, MODEL_RATE_HZ)
        samples = resample_poly(samples, MODEL_RATE_HZ // common, rate // common)
    return (np.clip(samples, -1.0, 1.0) * 32767).astype("<i2")


def _to_model_rate(source: Audio | str | os.PathLike[str]) -> np.ndarray:
    """A recording at the model's rate and format; a file is read block by block (a 2-hour 44.1 kHz file
    never holds more than its 16 kHz 16-bit form, 230 MB, in memory)."""
    if isinstance(source, Audio):
        return _resampled(source.samples, source.sample_rate_hz)
    from .audio import file_blocks

    rate, blocks = file_blocks(source, seconds_per_block=60.0)
    return np.concatenate([_resampled(block, rate) for block in blocks] or [np.zeros(0, "<i2")])


def _cuts(samples: np.ndarray) -> list[tuple[int, int]]:
    """Utterances of at most :data:`MAX_UTTERANCE_S`, cut at the quietest 10 ms before each limit."""
    limit, step = int(MAX_UTTERANCE_S * MODEL_RATE_HZ), MODEL_RATE_HZ // 100
    search = min(5 * MODEL_RATE_HZ, limit // 2)
    pieces, start = [], 0
    while samples.size - start > limit:
        window = samples[start + limit - search:start + limit].astype(float)
        energy = np.add.reduceat(window**2, np.arange(0, window.size, step))
        cut = start + limit - search + int(np.argmin(energy)) * step
        pieces.append((start, cut))
        start = cut
    pieces.append((start, samples.size))
    return pieces


def _label(word: str) -> str:
    """A decoder's unit name as a phone of :data:`PHONES` (fillers such as +NSN+ and <sil> are SIL)."""
    name = re.sub(r"\d", "", word.upper())
    return name if name in PHONES else "SIL"


def _decode_utterances(pieces: list[tuple[int, np.ndarray]]) -> list[Phone]:
    """Phone-loop decoding of (first sample, samples) utterances, each on its own: a fresh decoder for each,
    since a decoder carries its cepstral mean from one utterance to the next, and an utterance's phones must not
    depend on which ones came before it in the same process."""
    phones: list[Phone] = []
    for start, samples in pieces:
        decoder = _decoder(allphone=os.path.join(_model_dir(), "en-us-phone.lm.bin"), **PHONE_LOOP_SETTINGS)
        decoder.start_utt()
        decoder.process_raw(samples.tobytes(), full_utt=True)
        decoder.end_utt()
        offset = start / MODEL_RATE_HZ
        for segment in decoder.seg() or ():
            phones.append(Phone(_label(segment.word), offset + segment.start_frame / DECODER_FPS,
                                offset + (segment.end_frame + 1) / DECODER_FPS))
    return phones


def _phone_loop(samples: np.ndarray) -> list[Phone]:
    pieces = [(start, samples[start:end]) for start, end in _cuts(samples)]
    import multiprocessing
    import threading

    workers = min(os.cpu_count() or 1, len(pieces) // PARALLEL_UTTERANCES)
    # utterances are decoded independently, so the result is the same in one process or several: a long
    # recording's are shared among the cores (the decoder holds Python's lock while it works). Forked
    # workers need no importable main module (a script on standard input, a notebook), and forking is safe
    # only where this process runs no other Python thread (the live server's, a progress monitor's)
    if workers < 2 or threading.active_count() > 1 or "fork" not in multiprocessing.get_all_start_methods():
        return _decode_utterances(pieces)
    from concurrent.futures import ProcessPoolExecutor

    shares = [pieces[i::workers] for i in range(workers)]
    with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("fork")) as pool:
        parts = list(pool.map(_decode_utterances, shares))
    return sorted((phone for part in parts for phone in part), key=lambda phone: phone.start_s)


def transcript_words(text: str) -> list[str]:
    """The words of a transcript as the dictionary spells them: lower case, punctuation dropped (apostrophes
    inside words kept).

    Parameters
    ----------
    text : str
        The transcript.

    Returns
    -------
    list of str

    Examples
    --------
    >>> transcript_words("He turned -- sharply, and faced Gregson's desk.")
    ['he', 'turned', 'sharply', 'and', 'faced', "gregson's", 'desk']
    >>> transcript_words("héllo ñandú")  # letters of any alphabet stay in their word
    ['héllo', 'ñandú']
    """
    return re.findall(r"[^\W_]+(?:'[^\W_]+)*", text.lower())


#: Most words a second of speech can hold in a transcript (fast speech is 4-6 words a second), plus a margin
#: for short clips; a longer transcript is not this recording's (900 KB once took 1.5 GB for 3 s).
MAX_WORDS_PER_S = 12.0
MAX_WORDS_MARGIN = 20
#: Largest transcript file read.
MAX_TRANSCRIPT_BYTES = 1 << 20


def read_transcript(path: str | os.PathLike[str]) -> str:
    """The text of a transcript file: UTF-8 (with or without a byte-order mark), or UTF-16/32 with theirs (as
    Notepad saves "Unicode"); at most :data:`MAX_TRANSCRIPT_BYTES`.

    Parameters
    ----------
    path : str or path-like
        The text file.

    Returns
    -------
    str

    Raises
    ------
    ParameterError
        The file is not text (binary, or in an encoding without a byte-order mark other than UTF-8).
    OSError
        It cannot be read.
    """
    import codecs

    from .inputs import open_input

    with open_input(path, max_bytes=MAX_TRANSCRIPT_BYTES) as handle:
        data = handle.read()
    marks = ((codecs.BOM_UTF32_LE, "utf-32"), (codecs.BOM_UTF32_BE, "utf-32"), (codecs.BOM_UTF8, "utf-8-sig"),
             (codecs.BOM_UTF16_LE, "utf-16"), (codecs.BOM_UTF16_BE, "utf-16"))
    encoding = next((name for bom, name in marks if data.startswith(bom)), "utf-8")
    try:
        text = data.decode(encoding)
    except UnicodeDecodeError:
        text = None
    if text is None or "\0" in text:
        raise ParameterError(f"transcript {os.fspath(path)!r} is not a text file (UTF-8, or UTF-16 with its "
                             "byte-order mark): give the words said, as text")
    return text


#: The decoder's beams for a last try at aligning a transcript (PocketSphinx's defaults are 1e-48, 7e-29, 1e-48).
WIDE_BEAMS = {"beam": 1e-120, "wbeam": 1e-100, "pbeam": 1e-120}


def _aligned(samples: np.ndarray, words: list[str]) -> list[Phone] | None:
    """Phones of ``words`` aligned to the whole audio, or None where the text does not fit it.

    The first pass finds the words' path through the audio; its lattice search (``bestpath``) loses that path
    over long recordings (a 23 s paragraph of a synthetic voice: no path), so where it finds none, the forward
    search's own path is taken instead, then the same with wider beams (a British voice read with the American
    dictionary needed them)."""
    for settings in ({}, {"bestpath": False}, {"bestpath": False, **WIDE_BEAMS}):
        aligned = _aligned_with(_decoder(**settings), samples, words)
        if aligned is not None:
            return aligned
    return None


def _aligned_with(decoder, samples: np.ndarray, words: list[str]) -> list[Phone] | None:
    try:
        decoder.set_align_text(" ".join(words))
        # in blocks (full_utt=False): the whole-utterance mode loses the path through long pauses
        decoder.start_utt()
        decoder.process_raw(samples.tobytes(), full_utt=False)
        decoder.end_utt()
        if decoder.hyp() is None:
            return None
        decoder.set_alignment()
        decoder.start_utt()
        decoder.process_raw(samples.tobytes(), full_utt=False)
        decoder.end_utt()
        alignment = decoder.get_alignment()
    except RuntimeError:
        return None
    if alignment is None:
        return None
    return [Phone(_label(phone.name), phone.start / DECODER_FPS, (phone.start + phone.duration) / DECODER_FPS)
            for word in alignment for phone in word]


def recognise_phones(source: Audio | str | os.PathLike[str], *, transcript: str | None = None) -> list[Phone]:
    """The phones of a recording, in time order, covering it from start to end.

    Parameters
    ----------
    source : Audio or path
        Speech at any sample rate (resampled to 16 kHz for the model).
    transcript : str, optional
        What is said. With it, the words' dictionary pronunciations are aligned to the audio; without it,
        phones are recognised freely (a phone loop).

    Returns
    -------
    list of Phone
        Consecutive phones; gaps the decoder leaves are SIL.

    Raises
    ------
    PhoneRecognitionError
        PocketSphinx is not installed.

    Warns
    -----
    TranscriptWarning
        Words not in the dictionary (left out), or a transcript that does not fit the audio (phone loop used).

    Examples
    --------
    >>> t = np.arange(16000) / 16000
    >>> phones = recognise_phones(Audio(np.zeros(16000), 16000))
    >>> {phone.label for phone in phones}
    {'SIL'}
    """
    samples = _to_model_rate(source)
    duration_s = samples.size / MODEL_RATE_HZ
    phones: list[Phone] | None = None
    if transcript is not None:
        words = transcript_words(transcript)
        if not words:
            raise ParameterError("transcript has no words")
        most = int(MAX_WORDS_PER_S * duration_s) + MAX_WORDS_MARGIN
        if len(words) > most:
            raise ParameterError(f"the transcript has {len(words)} words, more than {most} that {duration_s:.1f} s "
                                 "of speech can hold: is it this recording's?")
        decoder = _decoder()
        unknown = [word for word in words if decoder.lookup_word(word) is None]
        known = [word for word in words if word not in unknown]
        if unknown:
            shown = ", ".join(sorted(set(unknown))[:10])
            warnings.warn(f"{len(unknown)} transcript word(s) not in the pronouncing dictionary, left out of the "
                          f"alignment: {shown}", TranscriptWarning, stacklevel=2)
        aligned = _aligned(samples, known) if known else None
        heard = _phone_loop(samples)
        agreement = _agreement(aligned, heard) if aligned is not None else 0.0
        if aligned is None:
            warnings.warn("the transcript could not be aligned to the audio (the aligner found no path through "
                          "its words); phones were recognised without it", TranscriptWarning, stacklevel=2)
            phones = heard
        elif agreement < MIN_AGREEMENT:
            warnings.warn(f"the transcript does not fit the audio (only {agreement:.0%} of its phones were heard "
                          "where it puts them); phones were recognised without it", TranscriptWarning,
                          stacklevel=2)
            phones = heard
        else:
            phones = aligned
    if phones is None:
        phones = _phone_loop(samples)
    return _covering(_quiet_as_silence(phones, samples), duration_s)


def _quiet_as_silence(phones: list[Phone], samples: np.ndarray) -> list[Phone]:
    """Phones heard in near-silence are silence: the decoder labels every stretch, even digital silence."""
    frame = MODEL_RATE_HZ // DECODER_FPS
    n = samples.size // frame
    if n == 0:
        return phones
    level = 10 * np.log10(np.mean((samples[:n * frame].reshape(n, frame) / 32768.0) ** 2, axis=1) + 1e-12)
    loud = np.quantile(level, 0.95)
    floor = max(QUIET_DBFS, loud - QUIET_BELOW_LOUD_DB)
    out = []
    for phone in phones:
        first = int(phone.start_s * DECODER_FPS)
        last = max(int(phone.end_s * DECODER_FPS), first + 1)
        quiet = level[first:last].size == 0 or float(np.max(level[first:last])) < floor
        out.append(Phone("SIL", phone.start_s, phone.end_s) if quiet else phone)
    return out


def _agreement(aligned: list[Phone], heard: list[Phone]) -> float:
    """Fraction of the aligned phones (silence aside) that the phone loop also heard, centred within 40 ms."""
    spoken = [phone for phone in aligned if phone.label != "SIL"]
    if not spoken:
        return 0.0
    centres: dict[str, list[float]] = {}
    for phone in heard:
        centres.setdefault(phone.label, []).append(phone.centre_s)
    found = sum(any(abs(phone.centre_s - c) <= 0.04 for c in centres.get(phone.label, ())) for phone in spoken)
    return found / len(spoken)


def _covering(phones: list[Phone], duration_s: float) -> list[Phone]:
    """Phones in order, overlaps trimmed, gaps (and the ends) filled with SIL, clipped to the recording."""
    out: list[Phone] = []
    time_s = 0.0
    for phone in sorted(phones, key=lambda p: p.start_s):
        start, end = max(phone.start_s, time_s), min(phone.end_s, duration_s)
        if end <= start:
            continue
        if start > time_s + 1e-9:
            out.append(Phone("SIL", time_s, start))
        out.append(Phone(phone.label, start, end))
        time_s = end
    if duration_s > time_s + 1e-9:
        out.append(Phone("SIL", time_s, duration_s))
    merged: list[Phone] = []
    for phone in out:  # one silence, not several in a row
        if merged and phone.label == "SIL" == merged[-1].label:
            merged[-1] = Phone("SIL", merged[-1].start_s, phone.end_s)
        else:
            merged.append(phone)
    return merged
