"""Lips from a transcript in any language: eSpeak NG's phones, their lip classes, and their alignment to a
recording whose phone times are known (eSpeak NG itself, at another speaking rate, padded with silence: its
own phone events give the true times)."""

from __future__ import annotations

import numpy as np
import pytest

from audio_features.audio import Audio
from audio_features.espeak import EspeakError, align_transcript, languages, phone_classes, speak
from prosody.cli import main
from prosody.errors import ConfigError, ParameterError
from prosody.motion.face.layer import lip_curves

pytest.importorskip("espeakng_loader", reason="eSpeak NG (pip install espeakng-loader)")

FPS = 100.0
#: Sentences whose bilabials (p, b, m) must close the lips, one per language.
SENTENCES = {"es": "Mamá bebe poco vino por la mañana.", "de": "Bitte mach mal eine Pause, Mama.",
             "fr": "Le bébé mange une pomme avec maman.", "cmn": "妈妈爱宝宝，爸爸不忙。"}
LEAD_S, TAIL_S = 0.5, 0.3


def _recording(text: str, language: str, *, rate_wpm: int = 130) -> tuple[Audio, list[float]]:
    """eSpeak NG saying ``text`` slower than the aligner's rendering, after 0.5 s of silence, and the true
    start of each bilabial."""
    from audio_features.espeak import _engine

    engine = _engine()
    engine.lib.espeak_SetParameter(1, rate_wpm, 0)
    try:
        spoken, phones = speak(text, language)
    finally:
        engine.lib.espeak_SetParameter(1, 175, 0)
    rate = spoken.sample_rate_hz
    samples = np.concatenate([np.zeros(int(LEAD_S * rate)), spoken.samples, np.zeros(int(TAIL_S * rate))])
    return Audio(samples, rate), [LEAD_S + p.start_s for p in phones if p.label == "P"]


def test_ipa_phones_fall_in_the_classes_that_look_alike() -> None:
    assert phone_classes("m") == ["P"] and phone_classes("β") == ["P"] and phone_classes("ɸ") == ["P"]
    assert phone_classes("f") == ["F"] and phone_classes("ð") == ["TH"] and phone_classes("ʁ") == ["K"]
    assert phone_classes("ˈyː") == ["UW"] and phone_classes("ø") == ["OW"] and phone_classes("ɑ̃") == ["AA"]
    assert phone_classes("tʃ") == ["CH"] and phone_classes("ts") == ["S"] and phone_classes("ɕ") == ["SH"]
    assert phone_classes("ai˥˩") == ["AA", "IY"]  # a diphthong with its tone: its vowels
    assert phone_classes("") == [] and phone_classes("_:") == []


def test_the_languages_asked_for_are_spoken() -> None:
    codes = languages()
    assert {"es", "de", "fr", "cmn", "en-us"} <= set(codes) and len(codes) > 100


@pytest.mark.parametrize("language", sorted(SENTENCES))
def test_bilabials_land_on_their_true_times_and_close_the_lips(language) -> None:
    text = SENTENCES[language]
    recording, truth = _recording(text, language)
    phones = align_transcript(recording, text, language)
    found = [p.start_s for p in phones if p.label == "P"]
    assert len(found) == len(truth) >= 4
    assert np.max(np.abs(np.array(found) - np.array(truth))) < 0.05  # within 50 ms
    n = int(recording.samples.size / recording.sample_rate_hz * FPS)
    curves = lip_curves(recording, n, fps=FPS, transcript=text, language=language)
    opening = curves[3] - curves[4] - curves[5]
    bilabials = [p for p in phones if p.label == "P"]
    for phone in bilabials:  # each closes: the opening at its middle is under a millimetre (~50 MNS)
        assert opening[int(phone.centre_s * FPS)] < 50, (phone, opening[int(phone.centre_s * FPS)])
    speaking = opening[int((LEAD_S + 0.1) * FPS):int(bilabials[0].start_s * FPS)]
    assert speaking.size == 0 or speaking.max() > 100  # and opens between


def test_a_sentence_without_bilabials_does_not_close_mid_utterance() -> None:
    text = "Ella tiene tres casas chicas al lado del lago."
    recording, truth = _recording(text, "es")
    assert truth == []
    n = int(recording.samples.size / recording.sample_rate_hz * FPS)
    curves = lip_curves(recording, n, fps=FPS, transcript=text, language="es")
    opening = curves[3] - curves[4] - curves[5]
    middle = opening[int((LEAD_S + 0.15) * FPS):n - int((TAIL_S + 0.15) * FPS)]
    assert middle.min() > 40  # never closed between the first and the last sound


def test_an_unknown_language_is_refused_with_how_to_list_them(capsys) -> None:
    with pytest.raises(EspeakError, match="prosody languages"):
        speak("hola", "xx-nowhere")
    from conftest import REPO

    assert main(["convert", str(REPO / "samples" / "arctic_a0009.wav"), "-o", "-", "--format", "json",
                 "--transcript", "hola", "--language", "xx"]) == 2
    assert "'prosody languages' lists the codes" in capsys.readouterr().err
    with pytest.raises(ConfigError, match="transcript"):
        lip_curves(Audio(np.zeros(1600), 16000), 10, fps=FPS, language="es")


@pytest.mark.parametrize("language", [".", "..", "./.", "!v/f1", "en+nonexistent", "en+" + "a" * 300, "/etc",
                                      "en/../../x", ""])
def test_languages_eSpeak_does_not_list_never_reach_it(language: str, tmp_path) -> None:
    """Paths and long variants crashed eSpeak NG (a segmentation fault, a buffer overflow): refused in one line
    with exit 2 before the audio is read, from the command line, Python and speak()."""
    import subprocess
    import sys

    from conftest import REPO

    done = subprocess.run([sys.executable, "-m", "prosody", "convert", str(REPO / "samples" / "arctic_a0009.wav"),
                           "-o", str(tmp_path / "x.fap"), "--transcript", "hello", "--language", language],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and "language" in done.stderr
    assert not (tmp_path / "x.fap").exists()
    from prosody.motion.settings import FaceSettings

    with pytest.raises(ParameterError):
        FaceSettings(transcript="hello", language=language)
    with pytest.raises(ParameterError):
        speak("hello", language)


@pytest.mark.parametrize("characters", [100_000, 1_000_000])
def test_a_transcript_longer_than_the_recording_can_hold_is_refused_at_once(characters: int) -> None:
    """100 KB of text on 3 s peaked at 3.6 GB; 1 MiB asked for 4.4 GiB in one array."""
    import time

    start = time.perf_counter()
    with pytest.raises(ParameterError, match="more than 320 that 3.0 s of speech can hold"):
        align_transcript(Audio(np.zeros(48000), 16000), "hola " * (characters // 5), "es")
    assert time.perf_counter() - start < 1.0


def test_known_codes_and_variants_are_spoken() -> None:
    assert speak("hello", "en+Alex")[0].samples.size > 0 and speak("hola", "es")[0].samples.size > 0


def test_prosody_languages_lists_the_codes(capsys) -> None:
    assert main(["languages"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "es\tSpanish (Spain)" in lines or any(line.startswith("es\t") for line in lines)
    assert len(lines) > 100


@pytest.mark.parametrize("code", ["en-gb", "zh", "es-mx", "fr-fr", "no", "pt-pt", "zh-yue", "hbs"])
def test_every_code_prosody_languages_lists_is_spoken(code):
    """12 of the codes listed were refused by the engine ('does not speak en-gb'): a code is not always a voice's
    name, so the voice is chosen by the file of the voice that lists the code first."""
    assert code in languages()
    audio, phones = speak("one two three", code)
    assert audio.samples.size > 0.3 * audio.sample_rate_hz and len(phones) >= 6


def test_a_code_takes_the_voice_that_speaks_it_first():
    """'en' is listed by several voices (British English first, the Caribbean voice too): it is British's."""
    assert languages()["en"] == languages()["en-gb"] == "English (Great Britain)"
    assert languages()["en-us"] == "English (America)"
