"""Phones of a transcript in any language eSpeak NG speaks, aligned to a recording.

eSpeak NG (the library and its data ship in the PyPI package ``espeakng-loader``; nothing is installed on the
system) says the transcript in the chosen language and reports each phone it says, in IPA, with the time it
starts in its own rendering. That rendering is then aligned to the recording by dynamic time warping of the two
signals' cepstra (c1-c12 of :mod:`audio_features.spectral`, each normalised over its own signal: the voices
differ, the sequence of sounds does not), which needs no acoustic model of the language; each phone's start
is carried through the warping path onto the recording.

Each IPA phone is put in the class of the ARPAbet phone that looks the same on the lips (the visemes read
those): bilabials (p b m, and the bilabial fricatives and approximants β ɸ) with P, labiodentals (f v ɱ ʋ)
with F, dentals (θ ð) with TH, the other coronal stops with T, velars, uvulars, pharyngeals and glottals with
K (h with HH), postalveolars, retroflex and alveolo-palatal sibilants and affricates with SH or CH, alveolar
sibilants with S, nasals, laterals, taps and trills with N or L, rhotic approximants with R; open vowels with
AA, mid front and central with EH, close front unrounded with IY (j with Y), close rounded (u y ʉ) with UW,
near-close rounded (ʊ ʏ) with UH, mid rounded (o ø ɵ) with OW, open-mid rounded (ɔ œ ɒ) with AO, w and ɥ with
W. Diacritics, stress, length and tone are dropped; a diphthong's time is shared by its vowels. The table is
:data:`IPA_CLASS`, and ``docs/languages.md`` lists it.
"""

from __future__ import annotations

import ctypes
import functools
import importlib.util
import threading
import unicodedata
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .audio import Audio
from .errors import ParameterError
from .phones import Phone
from .spectral import CEPSTRUM_RATE, N_CEPSTRA, cepstra

ESPEAK_PACKAGE = "espeakng_loader"
INSTALL_HINT = "pip install 'visual-prosody[languages]'"
#: Silence added before and after eSpeak's rendering, s (it absorbs the recording's own).
PAD_S = 0.25
#: The longest recording aligned in one piece, s (the warping's cost matrix grows with its square).
MAX_ALIGN_S = 120.0
#: A transcript of more characters than this per second of the recording (and the margin) is not its own:
#: fast speech says about 20 a second, written with spaces and punctuation.
MAX_CHARACTERS_PER_S, MAX_CHARACTERS_MARGIN = 40.0, 200
#: Cost-matrix cells kept at most; longer recordings are aligned on coarser frames.
MAX_CELLS = 16_000_000

# eSpeak NG's C interface (speak_lib.h)
_SYNCHRONOUS = 2
_PHONEME_EVENTS, _PHONEME_IPA, _DONT_EXIT = 0x0001, 0x0002, 0x8000
_EVENT_END_OF_LIST, _EVENT_PHONEME = 0, 7
_POS_CHARACTER, _CHARS_UTF8 = 1, 1

_CLASSES = {
    "P": "pbmɸβʙɓ", "F": "fvɱʋ", "TH": "θð", "T": "tdʈɖɗ", "K": "kgɡqɢxɣχʁħʕʔŋɴʀɠʛ", "HH": "hɦ",
    "SH": "ʃʒɕʑʂʐçʝ", "S": "sz", "N": "nɲɳ", "L": "lɫɭʎʟɾɽrɺɬɮ", "R": "ɹɻ",
    "AA": "aäɑæɐʌɶ", "EH": "eɛəɘɜɞɤ", "IY": "iɪɨ", "Y": "j", "UW": "uyʉɯ", "UH": "ʊʏ",
    "OW": "oøɵ", "AO": "ɔœɒ", "W": "wɥɰ",
}
#: IPA symbol -> the ARPAbet class that looks the same on the lips.
IPA_CLASS: dict[str, str] = {symbol: label for label, symbols in _CLASSES.items() for symbol in symbols}
#: Affricates written as two symbols: one phone.
AFFRICATES = {"tʃ": "CH", "dʒ": "CH", "tɕ": "CH", "dʑ": "CH", "ʈʂ": "CH", "ts": "S", "dz": "S", "pf": "F"}
_VOWEL_CLASSES = {"AA", "EH", "IY", "UW", "UH", "OW", "AO"}
#: Marks dropped from eSpeak's phone names: stress, length, tone letters and digits, and other modifiers.
_DROPPED = set("ˈˌːˑ˥˦˧˨˩ʰʲʷˠˤ˞ⁿˡ-_|‖.0123456789")


class EspeakError(ParameterError):
    """eSpeak NG is missing, or does not speak the language asked for."""


@dataclass(frozen=True)
class SpokenPhone:
    """A phone of eSpeak's rendering: its IPA name, class, and start in that rendering.

    Attributes
    ----------
    ipa : str
        The phone as eSpeak NG names it.
    label : str
        Its lip class.
    start_s : float
        Its start in eSpeak NG's rendering, in s.
    """

    ipa: str
    label: str
    start_s: float


def phone_classes(name: str) -> list[str]:
    """The lip classes of one of eSpeak's IPA phone names (a diphthong gives one per vowel; pauses none).

    Parameters
    ----------
    name : str
        A phone as eSpeak NG names it in IPA (stress marks and length allowed).

    Returns
    -------
    list of str
        Lip classes, in order.

    Examples
    --------
    >>> phone_classes("ˈa"), phone_classes("tʃ"), phone_classes("aʊ"), phone_classes("ɑː"), phone_classes("")
    (['AA'], ['CH'], ['AA', 'UH'], ['AA'], [])
    """
    text = "".join(ch for ch in unicodedata.normalize("NFD", name)
                   if unicodedata.category(ch) != "Mn" and ch not in _DROPPED)
    out: list[str] = []
    k = 0
    while k < len(text):
        pair = text[k:k + 2]
        if pair in AFFRICATES:
            out.append(AFFRICATES[pair])
            k += 2
            continue
        label = IPA_CLASS.get(text[k])
        if label is not None and not (out and label == out[-1] and label not in _VOWEL_CLASSES):
            out.append(label)
        k += 1
    return out


def _library_paths() -> tuple[str, str]:
    spec = importlib.util.find_spec(ESPEAK_PACKAGE)
    if spec is None or not spec.submodule_search_locations:
        raise EspeakError(f"a transcript in another language needs eSpeak NG: {INSTALL_HINT}")
    folder = Path(next(iter(spec.submodule_search_locations)))
    return str(folder / "libespeak-ng.so"), str(folder / "espeak-ng-data")


class _EventId(ctypes.Union):
    _fields_ = [("number", ctypes.c_int), ("name", ctypes.c_char_p), ("string", ctypes.c_char * 8)]


class _Event(ctypes.Structure):
    _fields_ = [("type", ctypes.c_int), ("unique_identifier", ctypes.c_uint), ("text_position", ctypes.c_int),
                ("length", ctypes.c_int), ("audio_position", ctypes.c_int), ("sample", ctypes.c_int),
                ("user_data", ctypes.c_void_p), ("id", _EventId)]


class _Voice(ctypes.Structure):
    _fields_ = [("name", ctypes.c_char_p), ("languages", ctypes.c_void_p), ("identifier", ctypes.c_char_p),
                ("gender", ctypes.c_ubyte), ("age", ctypes.c_ubyte), ("variant", ctypes.c_ubyte),
                ("xx1", ctypes.c_ubyte), ("score", ctypes.c_int), ("spare", ctypes.c_void_p)]


_CALLBACK = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.POINTER(ctypes.c_short), ctypes.c_int, ctypes.POINTER(_Event))


class _Engine:
    """eSpeak NG in synchronous mode (one per process: the library keeps global state)."""

    def __init__(self) -> None:
        library, data = _library_paths()
        try:
            self.lib = ctypes.CDLL(library)
        except OSError as error:
            raise EspeakError(f"eSpeak NG's library cannot be loaded ({error}): {INSTALL_HINT}") from None
        self.lib.espeak_ListVoices.restype = ctypes.POINTER(ctypes.POINTER(_Voice))
        self.rate = int(self.lib.espeak_Initialize(_SYNCHRONOUS, 0, data.encode(),
                                                   _PHONEME_EVENTS | _PHONEME_IPA | _DONT_EXIT))
        if self.rate <= 0:
            raise EspeakError(f"eSpeak NG did not start (its data at {data})")
        self.lock = threading.Lock()
        self._samples: list[np.ndarray] = []
        self._phones: list[tuple[str, int]] = []
        self._callback = _CALLBACK(self._collect)  # kept: the library calls it back
        self.lib.espeak_SetSynthCallback(self._callback)

    def _collect(self, wav, count, events) -> int:
        if count > 0:
            self._samples.append(np.ctypeslib.as_array(wav, shape=(count,)).astype(np.float32) / 32768.0)
        k = 0
        while events[k].type != _EVENT_END_OF_LIST:
            event = events[k]
            if event.type == _EVENT_PHONEME:
                self._phones.append((event.id.string.decode("utf-8", "replace"), int(event.audio_position)))
            k += 1
        return 0

    def languages(self) -> dict[str, str]:
        return {code: name for code, (name, _) in self.voices.items()}

    @functools.cached_property
    def voices(self) -> dict[str, tuple[str, str]]:
        """Language code -> (name, identifier) of the voice that speaks it first (the lowest priority number
        eSpeak NG gives the code among its voices: "en" is British English's, not the Caribbean voice's)."""
        voices = self.lib.espeak_ListVoices(None)
        best: dict[str, tuple[int, str, str]] = {}
        k = 0
        while voices[k]:
            voice = voices[k].contents
            raw = ctypes.string_at(voice.languages, 256) if voice.languages else b""
            name = (voice.name or b"").decode("utf-8", "replace")
            identifier = (voice.identifier or b"").decode("utf-8", "replace")
            at = 0
            while at < len(raw) and raw[at] != 0:  # (priority byte, name, NUL) pairs up to an empty name
                end = raw.index(b"\0", at + 1)
                code = raw[at + 1:end].decode("utf-8", "replace")
                if code and (code not in best or raw[at] < best[code][0]):
                    best[code] = (raw[at], name, identifier)
                at = end + 1
            k += 1
        return {code: (name, identifier) for code, (_, name, identifier) in sorted(best.items())}

    @functools.cached_property
    def codes(self) -> frozenset[str]:
        return frozenset(self.languages())

    @functools.cached_property
    def variants(self) -> frozenset[str]:
        """The voice variants (``en+VARIANT``): the files of the data's ``voices/!v`` folder."""
        folder = Path(_library_paths()[1]) / "voices" / "!v"
        try:
            return frozenset(path.name for path in folder.iterdir() if path.is_file())
        except OSError:
            return frozenset()

    def check(self, language: str) -> None:
        """Refuse a language eSpeak NG does not list (a path or a long name reaches its file handling, which
        crashes on some): a code of :meth:`languages`, or one with ``+VARIANT`` of its variants."""
        code, plus, variant = language.partition("+")
        if code not in self.codes or (plus and variant not in self.variants):
            shown = language if len(language) <= 40 else language[:40] + "..."
            raise EspeakError(f"eSpeak NG does not speak {shown!r}: 'prosody languages' lists the codes"
                                 + (" (and a voice variant is one of eSpeak NG's voices/!v files)" if plus else ""))

    def say(self, text: str, language: str) -> tuple[np.ndarray, list[tuple[str, int]]]:
        self.check(language)
        code, plus, variant = language.partition("+")
        # by the voice's file: a code is not always a voice's name (en-gb, zh, pt-pt, no)
        voice = self.voices[code][1] + plus + variant
        with self.lock:
            if self.lib.espeak_SetVoiceByName(voice.encode()) != 0:
                raise EspeakError(f"eSpeak NG does not speak {language!r}: 'prosody languages' lists the codes")
            self._samples, self._phones = [], []
            data = text.encode("utf-8")
            self.lib.espeak_Synth(data, len(data) + 1, 0, _POS_CHARACTER, 0, _CHARS_UTF8, None, None)
            self.lib.espeak_Synchronize()
            samples = np.concatenate(self._samples) if self._samples else np.zeros(0, np.float32)
            return samples, list(self._phones)


@functools.lru_cache(maxsize=1)
def _engine() -> _Engine:
    return _Engine()


def check_language(language: str) -> None:
    """Refuse a language eSpeak NG does not list: nothing else reaches the library (paths and long variants
    crashed it).

    Parameters
    ----------
    language : str
        A code ``prosody languages`` shows, optionally ``+VARIANT`` with one of eSpeak NG's voice variants
        (``en+Alex``).

    Returns
    -------
    None

    Raises
    ------
    EspeakError
        eSpeak NG is missing, or does not list ``language`` (a :class:`ParameterError`).
    """
    if not isinstance(language, str) or not language:
        raise ParameterError(f"a language is an eSpeak NG code such as 'es' or 'de', got {language!r}")
    _engine().check(language)


def languages() -> dict[str, str]:
    """The language codes eSpeak NG speaks, with the name of a voice of each.

    Returns
    -------
    dict of str to str
        Language code -> a voice's name.
    """
    return _engine().languages()


def speak(text: str, language: str) -> tuple[Audio, list[SpokenPhone]]:
    """eSpeak NG saying ``text`` in ``language``: its audio and its phones with their start times.

    Parameters
    ----------
    text : str
        What is said.
    language : str
        An eSpeak NG language code (``prosody languages`` lists them).

    Returns
    -------
    audio : Audio
        eSpeak NG's rendering.
    phones : list of SpokenPhone
        Its phones, with their start times in the rendering.
    """
    if not text.strip():
        raise ParameterError("the transcript has no words")
    engine = _engine()
    samples, events = engine.say(text, language)
    total_s = samples.size / engine.rate
    phones = []
    for k, (name, position_ms) in enumerate(events):
        start = position_ms / 1000.0
        end = events[k + 1][1] / 1000.0 if k + 1 < len(events) else total_s
        classes = phone_classes(name) or ["SIL"]
        share = max(end - start, 0.0) / len(classes)  # a diphthong's vowels share its time
        for j, label in enumerate(classes):
            phones.append(SpokenPhone(name, label, start + j * share))
    return Audio(samples.astype(np.float64), engine.rate), phones


def _normalised(features: np.ndarray) -> np.ndarray:
    values = features[:, 1:N_CEPSTRA]
    return (values - values.mean(axis=0)) / (values.std(axis=0) + 1e-9)


def align_transcript(recording: Audio, transcript: str, language: str) -> list[Phone]:
    """The transcript's phones on the recording's time line, labelled by lip class (see the module doc).

    Parameters
    ----------
    recording : Audio
        The recording the transcript is said in.
    transcript : str
        What is said.
    language : str
        An eSpeak NG language code.

    Returns
    -------
    list of Phone
        Labelled by lip class, with start and end times on the recording.

    Raises
    ------
    EspeakError
        eSpeak NG is missing or does not speak ``language``.
    ParameterError
        The recording is longer than :data:`MAX_ALIGN_S` (split it), the transcript is empty or longer than the
        recording can hold (:data:`MAX_CHARACTERS_PER_S`).
    """
    from .errors import require_extra

    require_extra(("librosa",), "languages", "aligning a transcript in another language")
    duration = recording.samples.size / recording.sample_rate_hz
    if duration > MAX_ALIGN_S:
        raise ParameterError(f"a transcript is aligned on recordings up to {MAX_ALIGN_S:.0f} s, this one has "
                             f"{duration:.0f} s: split it into lines")
    most = int(MAX_CHARACTERS_PER_S * duration) + MAX_CHARACTERS_MARGIN
    if len(transcript) > most:  # eSpeak NG's rendering, and the alignment's memory, grow with the text
        raise ParameterError(f"the transcript has {len(transcript)} characters, more than {most} that {duration:.1f} "
                             "s of speech can hold: is it this recording's?")
    spoken, phones = speak(transcript, language)
    pad = np.zeros(int(PAD_S * spoken.sample_rate_hz))
    rendering = Audio(np.concatenate([pad, spoken.samples, pad]), spoken.sample_rate_hz)
    ours, theirs = _normalised(cepstra(recording)), _normalised(cepstra(rendering))
    step = max(1, int(np.ceil(np.sqrt(ours.shape[0] * theirs.shape[0] / MAX_CELLS))))
    ours, theirs = ours[::step], theirs[::step]
    squared = (theirs ** 2).sum(axis=1)[:, None] + (ours ** 2).sum(axis=1)[None, :] - 2.0 * theirs @ ours.T
    cost = np.sqrt(np.maximum(squared, 0.0))
    import librosa

    _, path = librosa.sequence.dtw(C=cost, backtrack=True)
    path = path[::-1]
    # for each frame of the rendering, the mean recording frame it is matched with
    frames_per_s = CEPSTRUM_RATE / step
    rendering_frames = np.arange(theirs.shape[0])
    sums = np.bincount(path[:, 0], weights=path[:, 1], minlength=theirs.shape[0])
    counts = np.maximum(np.bincount(path[:, 0], minlength=theirs.shape[0]), 1)
    matched = sums / counts

    def on_recording(time_s: float) -> float:
        return float(np.interp((time_s + PAD_S) * frames_per_s, rendering_frames, matched)) / frames_per_s

    starts = [on_recording(phone.start_s) for phone in phones]
    spoken_end = spoken.samples.size / spoken.sample_rate_hz
    ends = starts[1:] + [on_recording(spoken_end)]
    out: list[Phone] = []
    for phone, start, end in zip(phones, starts, ends, strict=True):
        end = max(end, start)
        if out and out[-1].label == phone.label == "SIL":
            continue
        out.append(Phone(phone.label, min(start, duration), min(end, duration)))
    return _filled(out, duration)


def _filled(phones: list[Phone], duration_s: float) -> list[Phone]:
    """Consecutive phones from 0 to the end, silence before, between (where eSpeak paused) and after."""
    out: list[Phone] = []
    time_s = 0.0
    for phone in phones:
        start = max(phone.start_s, time_s)
        if start > time_s + 1e-9:
            out.append(Phone("SIL", time_s, start))
        if phone.end_s > start:
            out.append(Phone(phone.label, start, phone.end_s))
            time_s = phone.end_s
    if duration_s > time_s + 1e-9:
        out.append(Phone("SIL", time_s, duration_s))
    return out
