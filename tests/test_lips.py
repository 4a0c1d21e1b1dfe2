"""Lips and expressions: dominance blending with known answers, phones, Eq. 14, and whole recordings."""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
import pytest
import soundfile
from conftest import harmonic_tone, segments

from audio_features import Audio, load_audio
from audio_features.phones import Phone, TranscriptWarning, recognise_phones, transcript_words
from prosody.cli import main
from prosody.errors import ConfigError
from prosody.fap.fapfile import read_fap
from prosody.motion.face.expressions import (
    EXPRESSIONS,
    ExpressionSegment,
    add_brow_raises,
    expression_curves,
    mix_with_lips,
    parse_expressions,
)
from prosody.motion.face.layer import lip_curves
from prosody.motion.face.lips import (
    LIP_FAPS,
    MIN_OPEN_MNS,
    PHONE_ORDER,
    VISEME_FAP,
    VISEME_OF_PHONE,
    VISEMES,
    MouthShape,
    blend,
    dominance,
    fit_shapes,
    inner_opening,
    phone_weights,
    said_visemes,
    shape_faps,
    shapes_from_phones,
    viseme_of,
)

SR = 16000


def _blend(times, segments, targets, *, theta=10.0, alpha=1.0):
    n = len(segments)
    return blend(np.asarray(times, float), segments, np.asarray(targets, float), alphas=[alpha] * n,
                 thetas_before=[theta] * n, thetas_after=[theta] * n)


def test_two_dominance_functions_give_the_known_values():
    # targets 0 and 100, centres 0.5 s apart, theta 10/s, alpha 1, c 1
    values = _blend([0.25, 0.5, 0.0], [(0.0, 0.0), (0.5, 0.5)], [0.0, 100.0])
    assert values[0] == pytest.approx(50.0, abs=5e-4)
    assert values[1] == pytest.approx(100 / (1 + np.exp(-5.0)), abs=1e-9)
    assert round(float(values[1]), 3) == 99.331
    assert values[2] == pytest.approx(100 * np.exp(-5.0) / (1 + np.exp(-5.0)))


def test_one_segment_gives_a_constant_and_a_blend_stays_within_its_targets(rng):
    times = np.linspace(-2, 5, 400)
    np.testing.assert_allclose(_blend(times, [(0.3, 0.8)], [42.0]), 42.0)
    for _ in range(50):
        k = int(rng.integers(2, 8))
        starts = np.sort(rng.uniform(0, 3, k))
        segs = [(s, s + float(rng.uniform(0, 0.3))) for s in starts]
        targets = rng.normal(0, 100, k)
        values = blend(times, segs, targets, alphas=rng.uniform(0.1, 20, k), thetas_before=rng.uniform(1, 80, k),
                       thetas_after=rng.uniform(1, 80, k))
        assert values.min() >= targets.min() - 1e-9 and values.max() <= targets.max() + 1e-9


def test_dominance_is_flat_inside_a_segment_and_asymmetric_outside():
    times = np.array([0.0, 0.1, 0.2, 0.3, 0.5])
    d = dominance(times, start_s=0.1, end_s=0.3, alpha=2.0, theta_before=10.0, theta_after=20.0)
    np.testing.assert_allclose(d, [2 * np.exp(-1.0), 2, 2, 2, 2 * np.exp(-4.0)])


def test_a_bilabial_closes_the_lips_between_open_vowels():
    phones = [Phone("AA", 0.0, 0.2), Phone("P", 0.2, 0.23), Phone("AA", 0.23, 0.43)]
    opening = inner_opening(shape_faps(shapes_from_phones(phones, 13, fps=30)))
    # the /p/ at 0.2-0.23 s: lips together (22 MNS, under half a millimetre: a thirtieth of the /a/'s opening)
    assert opening[6] <= 30
    assert opening[2] > 250 and opening[11] > 250  # the vowels open


def test_only_silence_and_bilabials_close_the_lips_and_cues_keep_the_rest_open():
    from prosody.fap import mouth_cues

    closed = {v.name for v in VISEMES if v.opening == 0}
    assert closed == {"neutral", "p_b_m"}
    for viseme in VISEMES:
        if viseme.name not in closed | {"f_v"}:  # /f v/: the lower lip under the teeth, nearly closed
            assert viseme.opening >= MIN_OPEN_MNS > mouth_cues.CLOSED_MNS, viseme
            assert min(viseme.opening_of(phone) for phone in viseme.phones) >= MIN_OPEN_MNS, viseme


def test_fitting_the_shapes_recovers_known_openings_within_their_bounds():
    rng = np.random.default_rng(3)
    weights = rng.dirichlet(np.ones(15), size=600)
    truth = np.linspace(0.0, 560.0, 15)
    truth[1] = 0.0
    target = weights @ truth
    np.testing.assert_allclose(fit_shapes([weights], [target], nonnegative=True, ridge=1e-9), truth, atol=1e-3)
    # a viseme whose least opening is above its fitted one is held at that least opening, the rest refitted
    floor = np.zeros(15)
    floor[2] = 200.0  # its true opening is 80
    fitted = fit_shapes([weights], [target], nonnegative=True, ridge=1e-9, minimum=floor)
    assert fitted[2] == pytest.approx(200.0) and fitted[1] == 0.0
    assert np.abs(fitted - truth)[3:].max() < 60.0  # the others absorb what it cannot take


def test_each_phone_opens_by_its_own_opening_and_blends_with_its_neighbours():
    a = next(v for v in VISEMES if v.name == "a")
    assert a.opening_of("AH") < a.opening_of("AA")  # a schwa opens less than an /aa/ of the same viseme
    held = [Phone("AA", 0.0, 1.0), Phone("AH", 1.0, 2.0)]
    opening = inner_opening(shape_faps(shapes_from_phones(held, 60, fps=30)))
    # each held phone at its own opening, but for its neighbour's dominance (under a few thousandths of it here)
    assert opening[5] == pytest.approx(a.opening_of("AA"), rel=2e-3)
    assert opening[55] == pytest.approx(a.opening_of("AH"), rel=2e-3)
    # the same phones with the viseme's one opening (a table without phone openings): both at it
    table = tuple(replace(v, phone_openings=None) for v in VISEMES)
    flat = inner_opening(shape_faps(shapes_from_phones(held, 60, fps=30, visemes=table)))
    np.testing.assert_allclose(flat, a.opening)
    # the phones' weights: each phone's share of the blend, rows summing to 1, that make the opening
    weights = phone_weights(np.arange(60) / 30, held)
    np.testing.assert_allclose(weights.sum(axis=1), 1.0)
    openings = np.array([VISEME_OF_PHONE[p].opening_of(p) for p in PHONE_ORDER])
    np.testing.assert_allclose(weights @ openings, opening)


def test_the_opening_is_shared_by_jaw_and_lips_and_the_outer_lips_follow():
    faps = shape_faps(shapes_from_phones([Phone("AA", 0.0, 1.0)], 30, fps=30))
    assert set(faps) == set(LIP_FAPS) | {VISEME_FAP}
    a = next(v for v in VISEMES if v.name == "a")
    np.testing.assert_allclose(inner_opening(faps), a.opening_of("AA"))
    np.testing.assert_allclose(faps[3], 0.6 * a.opening_of("AA"))
    np.testing.assert_allclose(faps[51], faps[4])
    np.testing.assert_allclose(faps[52], faps[5])
    rounded = shape_faps(shapes_from_phones([Phone("UW", 0.0, 1.0)], 30, fps=30))
    assert rounded[16][15] > 0 and rounded[6][15] < 0  # /u/ protrudes and narrows
    assert viseme_of("B").number == viseme_of("M").number == 1 and viseme_of("IY2").name == "i"


def test_eq14_same_sign_opposite_sign_and_rest():
    lips = {12: np.array([10.0, -10.0, 0.0, 40.0]), 3: np.array([100.0, 0.0, 0.0, 0.0])}
    expression = {12: np.array([30.0, 30.0, 30.0, -20.0]), 31: np.array([5.0, 5.0, 5.0, 5.0])}
    mixed = mix_with_lips(lips, expression, delta=0.5)
    np.testing.assert_allclose(mixed[12], [20.0, -10.0, 30.0, 40.0])
    np.testing.assert_allclose(mixed[3], lips[3])  # the expression does not move it
    np.testing.assert_allclose(mixed[31], 5.0)  # the visemes do not move it
    np.testing.assert_allclose(mix_with_lips({12: np.array([10.0])}, {12: np.array([30.0])}, delta=0.25)[12], 25.0)


@pytest.mark.parametrize("name", sorted(EXPRESSIONS))
def test_each_expression_sets_a_lip_corner_on_both_contours_alike(name):
    # Xface copies the inner corners to the outer ones, Greta does not: set both so the two players agree
    targets = EXPRESSIONS[name]
    for inner, outer in ((12, 59), (13, 60), (6, 53), (7, 54)):
        assert targets.get(inner) == targets.get(outer), (name, inner, outer)


def test_expressions_blend_in_and_out_and_brows_stay_in_range():
    segments = [ExpressionSegment("joy", 0.5, 1.0, 2.0)]
    curves = expression_curves(segments, 120, fps=30)
    corner = curves[12]
    assert corner[45] == pytest.approx(0.5 * EXPRESSIONS["joy"][12] / (1 + 0.02), rel=1e-6)
    assert corner[0] < 0.02 * corner[45] and corner[-1] < 0.001 * corner[45]  # neutral 1 s and 2 s away
    assert 0.5 * corner[45] < corner[25] < corner[45]  # on its way in 0.17 s before the start
    assert np.all(np.diff(corner[:30]) >= 0)
    whole = expression_curves(parse_expressions("surprise"), 30, fps=30)
    np.testing.assert_allclose(whole[31], EXPRESSIONS["surprise"][31] / 1.02)
    raised = add_brow_raises({31: whole[31]}, {31: np.full(30, 300.0), 32: np.full(30, 10.0)})
    assert raised[31].max() <= 400 and raised[32][0] == 10.0


@pytest.mark.parametrize("spec, message", [
    ("happiness:0.5", "unknown expression"), ("joy:1.5", "intensity must be in"), ("joy:lots", "NAME:INTENSITY"),
    ("missing.csv", "no such expression file"),
])
def test_bad_expressions_are_refused(spec, message):
    with pytest.raises(ConfigError, match=message):
        parse_expressions(spec)


def test_timed_expression_file(tmp_path):
    path = tmp_path / "timed.csv"
    path.write_text("start_s,end_s,expression,intensity\n0.5,1.5,anger,0.8\n2.0,3.0,sadness,1\n")
    segments = parse_expressions(str(path))
    assert segments == [ExpressionSegment("anger", 0.8, 0.5, 1.5), ExpressionSegment("sadness", 1.0, 2.0, 3.0)]
    path.write_text("start_s,end_s,expression,intensity\n1.5,0.5,anger,0.8\n")
    with pytest.raises(ConfigError, match="start_s < end_s"):
        parse_expressions(str(path))


def test_silence_gives_a_closed_still_mouth():
    silence = Audio(np.zeros(2 * SR), SR)
    assert {phone.label for phone in recognise_phones(silence)} == {"SIL"}
    faps = lip_curves(silence, 60, fps=30)
    assert all(np.all(curve == 0) for curve in faps.values())
    quiet_hum = Audio(1e-5 * np.sin(2 * np.pi * 50 * np.arange(2 * SR) / SR), SR)  # mains hum at -100 dBFS
    assert np.all(inner_opening(lip_curves(quiet_hum, 60, fps=30)) == 0)


def test_a_tone_and_steady_chords_leave_the_mouth_closed_or_nearly():
    # music is no speech: a sustained chord gives no opening anywhere near a vowel's
    t = np.arange(3 * SR) / SR
    chord = sum(0.15 * np.sin(2 * np.pi * f * t) for f in (261.6, 329.6, 392.0))
    opening = inner_opening(lip_curves(Audio(chord, SR), 90, fps=30))
    assert np.median(opening) <= 60


def test_an_aligner_that_gives_up_is_said_truthfully(monkeypatch):
    """Where the aligner finds no path, the warning says so (it said '0% of its phones were heard', a figure
    that was never measured)."""
    from audio_features import phones as phone_module

    monkeypatch.setattr(phone_module, "_aligned", lambda samples, words: None)
    audio = load_audio(_sample("arctic_a0009.wav"))
    with pytest.warns(TranscriptWarning, match="could not be aligned") as caught:
        phones = recognise_phones(audio, transcript="He turned sharply, and faced Gregson across the table.")
    assert not any("%" in str(w.message) for w in caught) and len(phones) > 10


@pytest.mark.slow
def test_transcript_words_and_a_transcript_that_does_not_fit(tmp_path):
    assert transcript_words("It's 5 o'clock -- isn't it?") == ["it's", "5", "o'clock", "isn't", "it"]
    audio = load_audio(_sample("arctic_a0009.wav"))
    # unrelated words: the aligner finds no path through them, or one whose phones are not heard
    with pytest.warns(TranscriptWarning, match="does not fit|could not be aligned"):
        phones = recognise_phones(audio, transcript="completely different words about cheese and bread")
    assert len(phones) > 10
    with pytest.warns(TranscriptWarning, match="not in the pronouncing dictionary.*xyzzy"):
        aligned = recognise_phones(audio, transcript="He turned sharply, and faced Gregson across the xyzzy table.")
    labels = [phone.label for phone in aligned if phone.label != "SIL"]
    assert labels[:8] == ["HH", "IY", "T", "ER", "N", "D", "SH", "AA"]


@pytest.mark.parametrize("encoding", ["utf-8", "utf-8-sig", "utf-16", "utf-16-be", "utf-32"])
def test_a_transcript_file_is_read_in_the_encodings_editors_save(tmp_path, encoding):
    from audio_features.phones import read_transcript

    path = tmp_path / "words.txt"
    text = "Héllo ñandú, it's 5 o'clock.\n"
    path.write_bytes(("\ufeff" if encoding == "utf-16-be" else "").encode(encoding) + text.encode(encoding))
    assert read_transcript(path).lstrip("\ufeff") == text
    assert transcript_words(read_transcript(path)) == ["héllo", "ñandú", "it's", "5", "o'clock"]


def test_a_binary_or_overlong_transcript_is_one_line(tmp_path, speech, capsys):
    from prosody.cli import main

    binary = tmp_path / "words.bin"
    binary.write_bytes(bytes(range(256)) * 4)
    assert main(["convert", str(speech), "--transcript", str(binary), "-o", str(tmp_path / "x.fap")]) == 2
    err = capsys.readouterr().err
    assert "is not a text file" in err and len(err.strip().splitlines()) == 1
    latin = tmp_path / "latin1.txt"
    latin.write_bytes("caf\xe9 cr\xe8me".encode("latin-1"))  # no byte-order mark, not UTF-8
    assert main(["convert", str(speech), "--transcript", str(latin), "-o", str(tmp_path / "x.fap")]) == 2
    assert "is not a text file" in capsys.readouterr().err
    long = tmp_path / "book.txt"
    long.write_text("word " * 100_000)  # 1.7 s of speech holds at most 12 x 1.7 + 20 = 40 words
    assert main(["convert", str(speech), "--transcript", str(long), "-o", str(tmp_path / "x.fap")]) == 2
    err = capsys.readouterr().err
    assert "the transcript has 100000 words, more than 40" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x.fap").exists()


@pytest.mark.shared_data
def test_phones_agree_with_the_labelled_alignment(shared_data):
    # arctic_a0009 comes with a hand-checked phone alignment (HTK label times in 100 ns)
    labelled = []
    for line in (shared_data / "speech" / "arctic_a0009_phone.lab").read_text().splitlines():
        start, end, label = line.split(maxsplit=2)
        phone = label.split("-", 1)[1].split("+", 1)[0].upper()
        labelled.append(Phone("SIL" if phone in ("SIL", "PAU") else phone, int(start) / 1e7, int(end) / 1e7))
    audio = load_audio(shared_data / "speech" / "arctic_a0009.wav")
    times = np.arange(int(audio.duration_s * 100)) / 100

    def classes(phones):
        out = np.zeros(times.size, int)
        for phone in phones:
            out[(times >= phone.start_s) & (times < phone.end_s)] = viseme_of(phone.label).number
        return out

    truth = classes(labelled)
    aligned = classes(recognise_phones(audio, transcript="he turned sharply and faced gregson across the table"))
    free = classes(recognise_phones(audio))
    assert np.mean(aligned == truth) > 0.75  # forced alignment: three quarters of the frames' visemes or more
    assert np.mean(free == truth) > 0.4  # the phone loop, without the words


def test_papa_mama_closes_the_lips_at_every_p_and_m(tmp_path):
    pytest.importorskip("espeakng_loader", reason="eSpeak NG (pip install espeakng-loader)")
    from audio_features.espeak import _engine, speak

    engine = _engine()
    engine.lib.espeak_SetParameter(1, 110, 0)  # eSpeak NG's rate, words a minute
    try:
        spoken, _ = speak("papa mama papa mama", "en-us")
    finally:
        engine.lib.espeak_SetParameter(1, 175, 0)
    wav = tmp_path / "papa.wav"
    soundfile.write(wav, spoken.samples, spoken.sample_rate_hz)
    audio = load_audio(wav)
    with warnings.catch_warnings():
        warnings.simplefilter("error", TranscriptWarning)  # the text must be used
        phones = recognise_phones(audio, transcript="papa mama papa mama")
    closures = [phone for phone in phones if phone.label in ("P", "M")]
    assert [phone.label for phone in closures] == ["P", "P", "M", "M", "P", "P", "M", "M"]
    n = int(audio.duration_s * 30)
    opening = inner_opening(shape_faps(shapes_from_phones(phones, n, fps=30)))
    for phone in closures:
        during = opening[int(phone.start_s * 30):int(phone.end_s * 30) + 1]
        assert during.min() <= 30, phone  # lips together (MNS: under half a millimetre)
    assert opening.max() > 250  # and the /a/ between them opens


def test_convert_writes_lips_in_every_condition_and_the_controls_leave_them_out(tmp_path):
    wav = tmp_path / "speech.wav"
    soundfile.write(wav, segments(SR, (0.3, 0, 0), (0.6, 140, 0.5), (0.5, 230, 0.5), (0.3, 0, 0)), SR)
    lips = {}
    for condition in ("speech", "none", "random"):
        out = tmp_path / f"{condition}.fap"
        assert main(["convert", str(wav), "-o", str(out), "--condition", condition]) == 0
        stream = read_fap(out).stream
        assert set(LIP_FAPS) <= set(stream.active_faps)
        lips[condition] = stream.curves(LIP_FAPS)
    np.testing.assert_array_equal(lips["speech"], lips["none"])
    np.testing.assert_array_equal(lips["speech"], lips["random"])
    out = tmp_path / "off.fap"
    assert main(["convert", str(wav), "-o", str(out), "--off", "lips"]) == 0
    assert not set(LIP_FAPS) & set(read_fap(out).stream.active_faps)
    half = tmp_path / "half.fap"
    assert main(["convert", str(wav), "-o", str(half), "--lip-gain", "0.5", "--lips", "acoustic"]) == 0
    whole = tmp_path / "whole.fap"
    assert main(["convert", str(wav), "-o", str(whole), "--lips", "acoustic"]) == 0
    np.testing.assert_allclose(read_fap(half).stream.curve(3), 0.5 * read_fap(whole).stream.curve(3), atol=1)


def test_an_expression_keeps_the_lips_articulating(tmp_path):
    wav = tmp_path / "speech.wav"
    soundfile.write(wav, harmonic_tone(150, 1.5, SR), SR)
    out = tmp_path / "joy.fap"
    assert main(["convert", str(wav), "-o", str(out), "--expression", "joy:0.8", "--lips", "acoustic"]) == 0
    stream = read_fap(out).stream
    assert stream.curve(12)[20] == pytest.approx(0.8 * EXPRESSIONS["joy"][12] / 1.02, abs=1)
    assert stream.curve(41)[20] > 0  # cheeks raised
    plain = tmp_path / "plain.fap"
    assert main(["convert", str(wav), "-o", str(plain), "--lips", "acoustic"]) == 0
    # jaw: viseme and smile both open it a little, so Eq. 14 averages them where both move it
    jaw_v, jaw = read_fap(plain).stream.curve(3), stream.curve(3)
    both = jaw_v > 0
    np.testing.assert_allclose(jaw[both], np.rint(0.5 * jaw_v[both] + 0.5 * 0.8 * 40 / 1.02), atol=1)


def _sample(name: str):
    from conftest import REPO

    return REPO / "samples" / name


def test_live_cepstra_do_not_depend_on_how_the_audio_arrives(rng):
    from audio_features.spectral import CepstraStream, cepstra

    samples = rng.normal(0, 0.1, 20000)
    whole = cepstra(Audio(samples, SR))
    live = CepstraStream(SR)
    parts, start = [], 0
    while start < samples.size:
        size = int(rng.integers(1, 900))
        parts.append(live.push(samples[start:start + size]))
        start += size
    parts.append(live.finish())
    np.testing.assert_allclose(np.vstack(parts), whole, atol=1e-9)


def test_live_lips_close_in_silence_and_open_on_a_voice():
    from prosody.live.converter import LiveConverter

    voice = segments(SR, (1.0, 0, 0), (1.0, 150, 0.5), (1.0, 0, 0))
    converter = LiveConverter(SR, condition="none")
    frames = []
    for start in range(0, voice.size, 160):
        frames += converter.push(voice[start:start + 160])
    frames += converter.finish()
    opening = np.array([f.faps[3] - f.faps[4] - f.faps[5] for f in frames])
    assert len(frames) == 90
    assert np.all(opening[5:25] == 0) and np.all(opening[70:] == 0)  # digital silence: closed
    assert opening[30:62].max() > 80  # the voice opens it (a steady tone is no speech: not throughout)


@pytest.mark.slow
def test_phones_of_a_long_recording_are_the_same_on_one_core_or_several(monkeypatch):
    import audio_features.phones as phones_module

    speech = load_audio(_sample("arctic_a0009.wav"))
    long = Audio(np.tile(speech.samples, 4), speech.sample_rate_hz)  # 12 s, cut into 2 s utterances
    monkeypatch.setattr(phones_module, "MAX_UTTERANCE_S", 2.0)
    monkeypatch.setattr(phones_module, "PARALLEL_UTTERANCES", 1)
    several = recognise_phones(long)
    monkeypatch.setattr(phones_module, "PARALLEL_UTTERANCES", 10**6)
    one = recognise_phones(long)
    assert several == one and len(one) > 40


def _live_opening(samples: np.ndarray, rate: int) -> np.ndarray:
    from prosody.live.converter import LiveConverter

    converter = LiveConverter(rate)
    frames = converter.push(samples) + converter.finish()
    return np.array([f.faps[3] - f.faps[4] - f.faps[5] for f in frames])


def test_the_live_mouth_closes_in_a_stops_silence():
    # a vowel-like tone, 90 ms of silence (a /p/'s closure), the tone again: the mouth closes in the gap
    from conftest import segments

    rate = 16000
    samples = segments(rate, (0.8, 140, 0.5), (0.09, 0, 0.0), (0.8, 150, 0.5))
    opening = _live_opening(samples, rate)
    t = np.arange(opening.size) / 30
    gap = (t > 0.82) & (t < 0.87)
    assert gap.any() and opening[gap].min() < 5
    assert np.median(opening[(t > 0.3) & (t < 0.7)]) > 100  # and opens on the vowel either side


@pytest.mark.shared_data
def test_the_live_mouth_closes_on_the_p_of_sharply(shared_data):
    import re

    samples, rate = soundfile.read(shared_data / "speech" / "arctic_a0009.wav")
    opening = _live_opening(samples, rate)
    labels = [line.split() for line in (shared_data / "speech" / "arctic_a0009_phone.lab").read_text().splitlines()]
    p_start, p_end = next((int(a) / 1e7, int(b) / 1e7) for a, b, name in labels
                          if re.search(r"-([^+]+)\+", name)[1] == "p")
    t = np.arange(opening.size) / 30
    assert opening[(t >= p_start) & (t <= p_end)].min() < 0.1 * np.median(opening[opening > 0])


@pytest.mark.parametrize("context", [3, None, True, "x", [0.1]])
def test_a_mouth_model_with_other_context_offsets_is_one_line(tmp_path, speech, capsys, context):
    import json
    from pathlib import Path

    from prosody.cli import main
    from prosody.motion.face.mouth_model import DEFAULT_MOUTH_MODEL_PATH

    payload = json.loads(Path(DEFAULT_MOUTH_MODEL_PATH).read_text()) | {"context_s": context}
    model = tmp_path / "mouth.json"
    model.write_text(json.dumps(payload))
    code = main(["convert", str(speech), "--lips", "acoustic", "--mouth-model", str(model), "-o",
                 str(tmp_path / "x.fap")])
    err = capsys.readouterr().err
    assert code == 1 and "field 'context_s' must list this release's offsets" in err and "Traceback" not in err


def test_combined_lips_are_the_mean_of_both_mouths_with_the_visemes_closures_kept() -> None:
    from conftest import REPO

    from audio_features import load_audio
    from prosody.motion.face.layer import COMBINED_CLOSED_MNS, lip_curves

    audio = load_audio(REPO / "samples" / "arctic_a0009.wav")
    n = 93
    visemes = inner_opening(lip_curves(audio, n, fps=30))
    acoustic = inner_opening(lip_curves(audio, n, fps=30, method="acoustic"))
    combined = inner_opening(lip_curves(audio, n, fps=30, method="combined"))
    closed = visemes < COMBINED_CLOSED_MNS
    assert closed.any() and (~closed).any()
    np.testing.assert_allclose(combined[closed], visemes[closed], atol=1e-9)
    np.testing.assert_allclose(combined[~closed], 0.5 * (visemes[~closed] + acoustic[~closed]), atol=1e-9)
    with pytest.raises(ConfigError, match="unknown lip method 'both'; choose visemes, acoustic, combined"):
        lip_curves(audio, n, fps=30, method="both")


def _openings_with_closures(starts, n=300, length=8):
    """An open mouth (300, swaying) closed (0) for ``length`` frames from each of ``starts``."""
    opening = 300.0 + 20 * np.sin(np.arange(n) / 7)
    for start in starts:
        opening[start:start + length] = 0.0
    return opening


def test_relative_closures_are_found_within_two_frames_and_at_the_lag() -> None:
    from prosody.measures import relative_closures

    starts = list(range(20, 290, 40))  # 7 closures of 8 frames: 19 % of the frames, over the 15th percentile
    recorded = _openings_with_closures(starts)
    exact = relative_closures(recorded, recorded, fps=30.0)
    assert exact["precision"] == exact["recall"] == exact["f1"] == 1.0
    near = relative_closures(_openings_with_closures([s + 2 for s in starts]), recorded, fps=30.0)
    # two frames late, every recorded closure is still found; the generated runs are longer than the recorded
    # ones' lowest frames (the recording is low-passed), so their ends may fall three frames away
    assert near["recall"] == 1.0 and near["precision"] > 0.9
    late = _openings_with_closures([s + 14 for s in starts])
    far = relative_closures(late, recorded, fps=30.0)
    assert far["precision"] == far["recall"] == 0.0 and far["f1"] is None
    assert relative_closures(late, recorded, fps=30.0, lag_frames=14)["f1"] == 1.0
    flicker = np.full(300, 300.0)
    flicker[::5] = 0.0  # a fifth of the frames closed, one at a time: no closure is two frames long
    assert relative_closures(flicker, recorded, fps=30.0) == {"precision": None, "recall": 0.0, "f1": None}
    unknown = np.full(300, np.nan)
    assert relative_closures(recorded, unknown, fps=30.0) == {"precision": None, "recall": None, "f1": None}

def test_two_measures_of_one_opening_agree_once_low_passed() -> None:
    from prosody.measures import opening_agreement

    frames = np.arange(300)
    opening = 0.1 + 0.05 * np.sin(2 * np.pi * 2.0 * frames / 30.0)  # a 2 Hz syllable rhythm at 30 fps
    blendshape = 0.3 + 2.0 * opening  # another scale and offset: the same curve
    assert opening_agreement(opening, blendshape, fps=30.0) == pytest.approx(1.0)
    assert opening_agreement(opening, -blendshape, fps=30.0) == pytest.approx(-1.0)
    # a 12 Hz tremor of the tracker is above the 8 Hz low-pass: the two still agree
    jitter = 0.15 * np.sin(2 * np.pi * 12.0 * frames / 30.0 + 0.3)
    assert np.corrcoef(opening, blendshape + jitter)[0, 1] < 0.6
    assert opening_agreement(opening, blendshape + jitter, fps=30.0) > 0.97
    # a measure that follows something else (a 0.7 Hz smile) does not
    smile = np.sin(2 * np.pi * 0.7 * frames / 30.0)
    assert abs(opening_agreement(opening, smile, fps=30.0)) < 0.1
    # frames unknown in either are left out; too few known, or a constant, has no answer
    gaps = blendshape.copy()
    gaps[100:150] = np.nan
    assert opening_agreement(opening, gaps, fps=30.0) == pytest.approx(1.0, abs=1e-3)
    assert opening_agreement(opening[:2], blendshape[:2], fps=30.0) is None
    assert opening_agreement(opening, np.full(300, 0.2), fps=30.0) is None
    assert opening_agreement(np.full(300, np.nan), blendshape, fps=30.0) is None


@pytest.mark.parametrize("with_jaw", [True, False])
def test_the_mouth_reader_keeps_the_jaw_blendshape_when_the_file_has_it(tmp_path, with_jaw) -> None:
    from prosody.fap.recorded import read_mouth_csv

    header = ["frame", "time_s", *(["jaw_open"] if with_jaw else []), "mouth_funnel", "mouth_pucker",
              "lip_opening", "mouth_width"]
    lines = [",".join(header)]
    for frame in range(4):
        jaw = [f"{0.1 * frame:.1f}"] if with_jaw else []
        opening = "" if frame == 2 else f"{0.02 * frame:.2f}"  # no face in frame 2
        lines.append(",".join([str(frame), f"{frame / 30:.4f}", *jaw, "0.1", "0.2", opening, "0.5"]))
    path = tmp_path / "clip.mouth.csv"
    path.write_text("\n".join(lines) + "\n")
    mouth = read_mouth_csv(path)
    assert np.allclose(mouth.lip_opening, [0.0, 0.02, np.nan, 0.06], equal_nan=True)
    assert np.allclose(mouth.rounding, 0.3) and np.allclose(mouth.mouth_width, 0.5)
    if with_jaw:
        assert np.allclose(mouth.jaw_open, [0.0, 0.1, 0.2, 0.3])
    else:
        assert mouth.jaw_open is None


def test_the_viseme_said_is_carried_as_fap_1_by_lips_from_phones() -> None:
    phones = [Phone("SIL", 0.0, 0.2), Phone("M", 0.2, 0.3), Phone("AA1", 0.3, 0.5), Phone("F", 0.5, 0.6),
              Phone("UW", 0.6, 0.8)]
    numbers = said_visemes(phones, 10, fps=10.0)
    assert numbers.tolist() == [0, 0, 1, 10, 10, 2, 14, 14, 0, 0]
    # phones given out of order, or overlapping a gap, are read by their times
    assert said_visemes(phones[::-1], 10, fps=10.0).tolist() == numbers.tolist()
    assert said_visemes([], 4, fps=10.0).tolist() == [0, 0, 0, 0]
    faps = shape_faps(shapes_from_phones(phones, 10, fps=10.0))
    assert faps[VISEME_FAP].tolist() == numbers.tolist()
    # a still mouth says nothing, and a mouth not made from phones has no viseme
    assert VISEME_FAP not in shape_faps(shapes_from_phones(phones, 10, fps=10.0), gain=0.0)
    assert VISEME_FAP not in shape_faps(MouthShape(np.full(3, 100.0), np.zeros(3), np.zeros(3)))


def test_the_viseme_fap_is_resampled_from_the_nearest_frame_and_never_written_to_fap_files(tmp_path) -> None:
    from prosody.fap.fapfile import format_fap
    from prosody.fap.stream import FapStream

    stream = FapStream.from_curves({1: np.array([0.0, 1.0, 10.0, 10.0, 2.0, 0.0]), 3: np.arange(6) * 30.0},
                                   fps=10.0)
    resampled = stream.resampled(25.0)
    assert set(resampled.curve(1).tolist()) <= {0.0, 1.0, 2.0, 10.0}  # never a viseme between two
    assert resampled.curve(3)[1] == pytest.approx(12.0)  # the low-level FAPs still interpolate
    mask_line = format_fap(stream).splitlines()[1].split()
    assert mask_line[0] == "0" and mask_line[2] == "1"  # FAP 1 masked off, FAP 3 on



PARAGRAPH = ("The quick brown fox jumps over the lazy dog. It was the best of times, it was the worst of times. "
             "Call me Ishmael. Some years ago, never mind how long precisely, having little or no money in my "
             "purse, and nothing particular to interest me on shore, I thought I would sail about a little and "
             "see the watery part of the world. It is a way I have of driving off the spleen and regulating the "
             "circulation.")


@pytest.mark.slow
@pytest.mark.parametrize("voice, rate", [("en-us", 16000), ("en-gb-x-rp", 22050), ("en", 16000)])
def test_a_paragraph_spoken_by_an_espeak_voice_aligns_with_its_exact_text(tmp_path, voice, rate):
    """The exact text an eSpeak NG voice spoke (a 23 s paragraph) was thrown away: the aligner's lattice search
    lost the path over the long recording. Now the transcript is used (no warning), and the phones it puts
    follow the words: every word's first phone is found in order."""
    pytest.importorskip("espeakng_loader", reason="eSpeak NG (pip install espeakng-loader)")
    from math import gcd

    from scipy.signal import resample_poly

    from audio_features.espeak import speak

    spoken, _ = speak(PARAGRAPH, voice)
    common = gcd(rate, spoken.sample_rate_hz)
    samples = resample_poly(spoken.samples, rate // common, spoken.sample_rate_hz // common)
    wav = tmp_path / "paragraph.wav"
    soundfile.write(wav, samples, rate)
    with warnings.catch_warnings():
        warnings.simplefilter("error", TranscriptWarning)  # the text must be used
        phones = recognise_phones(load_audio(wav), transcript=PARAGRAPH)
    said = [phone.label for phone in phones if phone.label != "SIL"]
    assert said[:9] == ["DH", "AH", "K", "W", "IH", "K", "B", "R", "AW"]  # the quick brow(n)
    assert said[-5:] == ["L", "EY", "SH", "AH", "N"]  # (circu)lation
    assert 0.9 * 23 * 10 < len(said) < 1.1 * 300  # about ten phones a second, all of them aligned


def test_a_live_frames_lip_values_are_the_offline_geometrys_to_the_bit() -> None:
    """The live path takes one frame's lips in plain floats (``shape_fap_values``); they must be exactly what
    ``shape_faps`` gives for the same shape, noise cut included (values under 1e-9 are 0)."""
    from prosody.motion.face.lips import shape_fap_values

    rng = np.random.default_rng(7)
    for opening, rounding, spread in [(200.0, 0.0, 0.0), (0.0, 0.0, 0.0), (1e-12, -1e-12, 3e-10),
                                      *rng.normal(0, [300.0, 0.2, 0.1], size=(50, 3)).tolist()]:
        offline = shape_faps(MouthShape(np.array([opening]), np.array([rounding]), np.array([spread])))
        live = shape_fap_values(opening, rounding, spread)
        assert live.keys() == offline.keys() - {VISEME_FAP}
        assert all(live[fap] == float(offline[fap][0]) for fap in live)
