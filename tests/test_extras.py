"""What serves one feature is an optional extra: without it the feature says, in one line, which extra to
install, and everything else works."""

from __future__ import annotations

import sys

import pytest
from conftest import harmonic_tone

from audio_features import Audio
from audio_features.errors import MissingExtraError, require_extra


def test_a_present_module_passes_and_a_missing_one_names_its_extra(monkeypatch) -> None:
    require_extra(("json", "csv"), "none", "reading")
    monkeypatch.setitem(sys.modules, "statsmodels", None)  # as if it were not installed
    with pytest.raises(MissingExtraError, match=r"^training needs statsmodels: pip install 'visual-prosody\[stats\]'$"):
        require_extra(("json", "statsmodels"), "stats", "training")


def test_training_without_statsmodels_says_which_extra(monkeypatch, tmp_path) -> None:
    from prosody.motion.training import train

    monkeypatch.setitem(sys.modules, "statsmodels", None)
    with pytest.raises(MissingExtraError, match=r"visual-prosody\[stats\]"):
        train(tmp_path, tmp_path / "model.json", kind="prosodic")


def test_opinion_scores_without_statsmodels_say_which_extra(monkeypatch) -> None:
    from prosody.study.ratings import analyze_ratings

    monkeypatch.setitem(sys.modules, "statsmodels", None)
    with pytest.raises(MissingExtraError, match=r"analysing opinion scores needs statsmodels: .*\[stats\]"):
        analyze_ratings([])


def test_another_language_without_librosa_says_which_extra(monkeypatch) -> None:
    from audio_features.espeak import align_transcript

    monkeypatch.setitem(sys.modules, "librosa", None)
    recording = Audio(harmonic_tone(150, 1.0, 16000), 16000)
    with pytest.raises(MissingExtraError, match=r"visual-prosody\[languages\]"):
        align_transcript(recording, "hola", "es")


def test_the_cli_says_it_in_one_line(monkeypatch, tmp_path, capsys) -> None:
    from prosody.cli import main

    monkeypatch.setitem(sys.modules, "statsmodels", None)
    (tmp_path / "data").mkdir()
    assert main(["train", "--data", str(tmp_path / "data"), "-o", str(tmp_path / "m.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["prosody train: error: training a prosodic head model needs statsmodels: pip install "
                   "'visual-prosody[stats]'"]
