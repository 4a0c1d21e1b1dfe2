"""Comparison metrics against hand-computed values, normalisation, `prosody compare` and `prosody batch`."""

from __future__ import annotations

import json
import os
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
import soundfile
from conftest import segments

from prosody.cli import main
from prosody.errors import ConfigError
from prosody.evaluation.compare import compare
from prosody.fap.stream import FapStream
from prosody.jobs.batch import BatchOptions, find_audio_files, find_ground_truth, run_batch
from prosody.measures import (
    canonical_correlations,
    fap_statistics,
    normalization_targets,
    normalize_stream,
    pearson,
    rmse,
)

SR = 16000


# metrics on small synthetic streams -----------------------------------------------------------------------
def test_statistics_against_hand_computed_values() -> None:
    generated = FapStream.from_curves({48: np.array([1.0, 2.0, 3.0, 4.0]), 31: np.zeros(4)}, fps=30)
    truth = FapStream.from_curves({48: np.array([2.0, 2.0, 4.0, 4.0])}, fps=30)
    stats = fap_statistics(generated, truth, faps=(31, 48, 49))
    # mean 2.5, population std sqrt(1.25); r = cov / (sd sd) = 1 / (sqrt(1.25) * 1) ; rmse sqrt((1+0+1+0)/4)
    assert stats["48"]["mean"] == pytest.approx(2.5)
    assert stats["48"]["std"] == pytest.approx(np.sqrt(1.25))
    assert stats["48"]["pearson_r"] == pytest.approx(1 / np.sqrt(1.25))
    assert stats["48"]["rmse"] == pytest.approx(np.sqrt(0.5))
    assert stats["31"] == {"mean": 0.0, "std": 0.0, "pearson_r": None, "rmse": None}  # truth lacks FAP 31
    assert stats["49"] == {"mean": None, "std": None, "pearson_r": None, "rmse": None}  # not generated


def test_pearson_and_rmse_edge_cases() -> None:
    assert pearson(np.array([1.0, 2.0, 3.0]), np.array([3.0, 2.0, 1.0])) == pytest.approx(-1.0)
    assert pearson(np.full(5, 7.0), np.arange(5.0)) is None
    assert rmse(np.array([0.0, 0.0]), np.array([3.0, 4.0])) == pytest.approx(np.sqrt(12.5))


def test_canonical_correlation_of_known_mixtures(rng) -> None:
    n = 5000
    shared = rng.standard_normal(n)
    x = np.column_stack([shared + 0.5 * rng.standard_normal(n), rng.standard_normal(n)])
    y = np.column_stack([rng.standard_normal(n), 2 * shared + rng.standard_normal(n), rng.standard_normal(n)])
    # the best pair is x0 with y1: corr = 2 / sqrt(1.25 * 5) = 0.8; the second canonical r is near 0
    values = canonical_correlations(x, y)
    assert values[0] == pytest.approx(0.8, abs=0.02)
    assert values[1] < 0.05
    # invariant to invertible linear maps of either side
    mixed = canonical_correlations(x @ [[2.0, 1.0], [0.3, -1.0]], y * [1.0, -3.0, 0.5])
    np.testing.assert_allclose(mixed, values, atol=1e-10)
    assert canonical_correlations(np.zeros((10, 2)), rng.standard_normal((10, 2))).size == 0


def test_normalisation_gives_equal_means_and_spreads(rng) -> None:
    truth = FapStream.from_curves({48: 500 + 2000 * rng.standard_normal(300)}, fps=30)
    small = FapStream.from_curves({48: 10 + 3 * rng.standard_normal(300), 31: rng.uniform(0, 5, 300)}, fps=30)
    large = FapStream.from_curves({48: 9000 * rng.standard_normal(300), 31: rng.uniform(0, 50, 300)}, fps=30)
    targets = normalization_targets({"a": small, "b": large}, reference=truth, faps=(31, 48))
    assert targets[48] == pytest.approx((truth.curve(48).mean(), truth.curve(48).std()))
    # FAP 31 is not in the truth: the average of the streams' own means and spreads
    expected_31 = (np.mean([small.curve(31).mean(), large.curve(31).mean()]),
                   np.mean([small.curve(31).std(), large.curve(31).std()]))
    assert targets[31] == pytest.approx(expected_31)
    for stream in (small, large):
        normalised = normalize_stream(stream, targets)
        for fap in (31, 48):
            assert normalised.curve(fap).mean() == pytest.approx(targets[fap][0])
            assert normalised.curve(fap).std() == pytest.approx(targets[fap][1])
        assert pearson(normalised.curve(48), stream.curve(48)) == pytest.approx(1.0)  # shape kept


# prosody compare ------------------------------------------------------------------------------------------
def _tone_file(path: Path) -> Path:
    soundfile.write(path, segments(SR, (0.5, 150, 0.5), (0.4, 250, 0.5), (0.6, 160, 0.5), (0.5, 0, 0)), SR)
    return path


def _head_csv(path: Path, n: int, rng) -> Path:
    angles = np.cumsum(0.002 * rng.standard_normal((n, 3)), axis=0)
    lines = ["frame,time_s,rx_rad,ry_rad,rz_rad"]
    lines += [f"{k},{k / 30:.6f},{a!r},{b!r},{c!r}" for k, (a, b, c) in enumerate(angles.tolist())]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.slow  # about 2 s of processor time when it is the first to import the report's plotting
def test_compare_cli_writes_everything_with_the_documented_shape(tmp_path, rng) -> None:
    audio = _tone_file(tmp_path / "tone.wav")
    truth = _head_csv(tmp_path / "tone.head.csv", 60, rng)
    out = tmp_path / "out"
    assert main(["compare", str(audio), "--ground-truth", str(truth), "-o", str(out), "--seed", "3"]) == 0
    names = {p.name for p in out.iterdir()}
    assert names == {"no_prosody.fap", "random.fap", "speech_driven.fap", "ground_truth.fap", "features.png",
                     "head.png", "report.md", "metrics.json"}
    metrics = json.loads((out / "metrics.json").read_text())
    assert list(metrics["conditions"]) == ["NO_PROSODY", "RANDOM", "SPEECH_DRIVEN", "GROUND_TRUTH"]
    head_keys = {"speed_envelope_r", "pitch_r", "std_ratio", "velocity_spectrum_distance_db", "yaw_r", "roll_r",
                 "speed_p10_ratio", "speed_p50_ratio", "speed_p90_ratio", "still_fraction", "recorded_still_fraction",
                 "still_offset_deg", "recorded_still_offset_deg"}
    for _condition, per_fap in metrics["conditions"].items():
        assert list(per_fap) == ["31", "32", "33", "34", "48", "49", "50", "head", "brows", "mouth"]
        for fap, entry in per_fap.items():
            if fap not in ("brows", "mouth"):
                assert set(entry) == (head_keys if fap == "head" else {"mean", "std", "pearson_r", "rmse"})
        assert per_fap["brows"]["raise_r"] is None  # this head.csv has no brows.csv beside it
        assert per_fap["mouth"]["opening_r"] is None  # nor a mouth.csv
        assert set(per_fap["head"]["std_ratio"]) == {"48", "49", "50"}
    assert set(metrics["controls"]["mismatched_audio"]) == head_keys
    assert metrics["seeds"] == 10 and metrics["head_model"] == "prosodic"
    truth_block = metrics["conditions"]["GROUND_TRUTH"]["head"]
    assert truth_block["speed_envelope_r"] == pytest.approx(1.0) and truth_block["pitch_r"] == pytest.approx(1.0)
    assert truth_block["velocity_spectrum_distance_db"] is None  # 60 frames: shorter than one Welch segment
    assert metrics["conditions"]["NO_PROSODY"]["head"]["std_ratio"] == {"48": 0.0, "49": 0.0, "50": 0.0}
    truth_head = metrics["conditions"]["GROUND_TRUTH"]["48"]
    assert truth_head["pearson_r"] == pytest.approx(1.0) and truth_head["rmse"] == pytest.approx(0.0)
    assert metrics["conditions"]["NO_PROSODY"]["48"]["pearson_r"] is None  # a still head: undefined
    assert metrics["conditions"]["GROUND_TRUTH"]["31"]["mean"] is None  # head.csv has no eyebrows
    assert metrics["cca"]["head_vs_ground_truth"]["GROUND_TRUTH"] == pytest.approx(1.0)
    # the rmse of the still condition is the recorded motion's root mean square (hand computed)
    rx = np.loadtxt(truth, delimiter=",", skiprows=1)[:, 2]
    recorded_au = (rx - np.median(rx)) * 1e5
    assert metrics["conditions"]["NO_PROSODY"]["48"]["rmse"] == pytest.approx(np.sqrt(np.mean(recorded_au**2)))
    assert (out / "features.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "## Agreement with the ground truth" in (out / "report.md").read_text()


def test_compare_normalize_matches_the_ground_truth_spread(tmp_path, rng) -> None:
    audio = _tone_file(tmp_path / "tone.wav")
    truth = _head_csv(tmp_path / "tone.head.csv", 60, rng)
    result = compare(audio, ground_truth=truth, normalize=True)
    stats = result.metrics["conditions"]
    for fap in ("48", "49", "50"):
        for condition in ("RANDOM", "SPEECH_DRIVEN"):
            assert stats[condition][fap]["mean"] == pytest.approx(stats["GROUND_TRUTH"][fap]["mean"], abs=1e-6)
            assert stats[condition][fap]["std"] == pytest.approx(stats["GROUND_TRUTH"][fap]["std"], rel=1e-9)
        assert stats["NO_PROSODY"][fap]["std"] == 0
    brows = [stats[c]["31"]["std"] for c in ("RANDOM", "SPEECH_DRIVEN")]
    assert brows[0] == pytest.approx(brows[1])  # no recorded brows: a common spread of their own


def test_compare_without_ground_truth(tmp_path) -> None:
    result = compare(_tone_file(tmp_path / "tone.wav"), seed=1)
    assert list(result.metrics["conditions"]) == ["NO_PROSODY", "RANDOM", "SPEECH_DRIVEN"]
    random = result.metrics["conditions"]["RANDOM"]
    assert all(random[str(fap)]["pearson_r"] is None for fap in (31, 32, 33, 34, 48, 49, 50))
    assert random["head"]["speed_envelope_r"] is None and random["head"]["std_ratio"]["48"] is None
    assert result.metrics["controls"]["mismatched_audio"]["pitch_r"] is None
    # accent rule: median voiced F0 160 Hz, threshold 4 semitones above it (201.6 Hz); the 250 Hz part is
    # frames 15-27, the first whose pitch window lies mostly inside it is 16, the raise ends where it does
    assert result.metrics["eyebrow_events"] == [[16, 27]]
    assert result.metrics["eyebrow_threshold_hz"] == pytest.approx(160 * 2 ** (4 / 12), rel=1e-3)


# prosody batch --------------------------------------------------------------------------------------------
@pytest.fixture
def corpus(tmp_path, rng) -> tuple[Path, Path]:
    indir = tmp_path / "in"
    (indir / "day1").mkdir(parents=True)
    truth = tmp_path / "truth"
    (truth / "day1").mkdir(parents=True)
    _tone_file(indir / "a.wav")
    _tone_file(indir / "day1" / "b.wav")
    _tone_file(indir / "day1" / "c.flac")
    (indir / "day1" / "broken.wav").write_text("not audio")
    (indir / "notes.txt").write_text("ignored")
    _head_csv(truth / "day1" / "b.head.csv", 60, rng)  # at the same relative path
    _head_csv(truth / "a.head.csv", 60, rng)  # at the top
    return indir, truth


def test_bootstrap_interval_of_known_samples() -> None:
    from prosody.jobs.batch import bootstrap_interval

    assert bootstrap_interval([]) is None
    assert bootstrap_interval([2.0]) == (2.0, 2.0)
    low, high = bootstrap_interval(np.arange(100.0))
    # the mean of 0..99 is 49.5 with a standard error of 28.9 / 10: the interval is about +-5.7 around it
    assert low == pytest.approx(49.5 - 1.96 * 2.887, abs=0.7) and high == pytest.approx(49.5 + 1.96 * 2.887, abs=0.7)
    assert bootstrap_interval(np.arange(100.0)) == (low, high)  # seeded


def test_find_files_and_ground_truth(corpus) -> None:
    indir, truth = corpus
    files = find_audio_files(indir)
    assert [str(f) for f in files] == ["a.wav", "day1/b.wav", "day1/broken.wav", "day1/c.flac"]
    assert find_ground_truth(Path("day1/b.wav"), truth) == truth / "day1" / "b.head.csv"
    assert find_ground_truth(Path("a.wav"), truth) == truth / "a.head.csv"
    assert find_ground_truth(Path("day1/c.flac"), truth) is None


@pytest.mark.slow
def test_batch_cli_mixes_good_broken_and_paired_files(corpus, tmp_path, capsys) -> None:
    indir, truth = corpus
    out = tmp_path / "out"
    code = main(["batch", str(indir), "-o", str(out), "--ground-truth-dir", str(truth)])
    err = capsys.readouterr().err
    assert code == 1  # something failed
    assert "day1/broken.wav" in err and err.count("error:") == 1
    summary = json.loads((out / "summary.json").read_text())
    assert summary["counts"] == {"done": 3, "skipped": 0, "failed": 1, "files": 4, "with_ground_truth": 2}
    by_file = {entry["file"]: entry for entry in summary["files"]}
    assert by_file["day1/broken.wav"]["status"] == "failed"
    assert "GROUND_TRUTH" in by_file["day1/b.wav"]["metrics"]["conditions"]
    assert "GROUND_TRUTH" not in by_file["day1/c.flac"]["metrics"]["conditions"]
    assert (out / "day1" / "b" / "ground_truth.fap").exists()
    assert (out / "day1" / "c" / "speech_driven.fap").exists()
    assert not (out / "day1" / "broken").exists() or not (out / "day1" / "broken" / "metrics.json").exists()
    assert summary["aggregate"]["GROUND_TRUTH"]["faps"]["48"] == {"pearson_r": pytest.approx(1.0), "files": 2}
    assert "| `day1/broken.wav` | failed" in (out / "summary.md").read_text()
    # measures over the recordings with truth: a mean and a bootstrap interval around it, and the controls
    truth_pitch = summary["measures"]["GROUND_TRUTH"]["head"]["pitch_r"]
    assert truth_pitch["mean"] == pytest.approx(1.0) and truth_pitch["recordings"] == 2
    assert truth_pitch["ci95"] == pytest.approx([1.0, 1.0])
    speech = summary["measures"]["SPEECH_DRIVEN"]["head"]["speed_envelope_r"]
    assert speech["ci95"][0] <= speech["mean"] <= speech["ci95"][1]
    assert set(summary["controls"]) == {"mismatched_audio", "mismatched_audio_brows", "mismatched_audio_mouth",
                                        "other_recordings"}
    assert summary["controls"]["other_recordings"]["pitch_r"]["recordings"] == 2
    assert by_file["a.wav"]["other_recordings_control"]["pitch_r"] is not None
    assert by_file["day1/c.flac"]["other_recordings_control"] is None  # no truth to compare with
    assert "own audio shifted (control)" in (out / "summary.md").read_text()

    # a re-run skips complete outputs; --force redoes them; a removed metrics.json makes one incomplete
    (out / "a" / "metrics.json").unlink()
    assert main(["batch", str(indir), "-o", str(out), "--ground-truth-dir", str(truth)]) == 1
    counts = json.loads((out / "summary.json").read_text())["counts"]
    assert (counts["done"], counts["skipped"]) == (1, 2)
    assert main(["batch", str(indir), "-o", str(out), "--ground-truth-dir", str(truth), "--force"]) == 1
    assert json.loads((out / "summary.json").read_text())["counts"]["done"] == 3
    # other settings are not "complete": a different seed redoes the files
    assert main(["batch", str(indir), "-o", str(out), "--ground-truth-dir", str(truth), "--seed", "9"]) == 1
    assert json.loads((out / "summary.json").read_text())["counts"]["done"] == 3


def test_batch_condition_subset_and_two_processes(corpus, tmp_path) -> None:
    indir, truth = corpus
    shutil.rmtree(indir / "day1")
    out = tmp_path / "out"
    summary = run_batch(indir, out, ground_truth_dir=truth, options=BatchOptions(conditions=("none", "random")),
                        jobs=2)
    assert summary["counts"]["failed"] == 0
    assert sorted(p.name for p in (out / "a").iterdir()) == ["features.csv", "metrics.json", "no_prosody.fap",
                                                            "random.fap"]


@pytest.mark.slow
def test_batch_on_a_local_dask_cluster(corpus, tmp_path) -> None:
    distributed = pytest.importorskip("distributed")
    indir, truth = corpus
    out = tmp_path / "out"
    # ":0": a free port for the dashboard (None still binds the default 8787, which may be taken)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, protocol="tcp",
                                  dashboard_address=":0") as cluster:
        code = main(["batch", str(indir), "-o", str(out), "--ground-truth-dir", str(truth),
                     "--scheduler", cluster.scheduler_address])
    assert code == 1
    counts = json.loads((out / "summary.json").read_text())["counts"]
    assert counts["done"] == 3 and counts["failed"] == 1


def test_batch_bad_usage(tmp_path, capsys) -> None:
    assert main(["batch", str(tmp_path / "missing"), "-o", str(tmp_path / "o")]) == 2
    assert "not a folder" in capsys.readouterr().err
    assert main(["batch", str(tmp_path), "-o", str(tmp_path / "o"), "--condition", "loud"]) == 2
    assert "unknown condition" in capsys.readouterr().err


# batch: what an unlucky run meets ----------------------------------------------------------------------
def test_same_stem_inputs_get_their_own_folders(tmp_path) -> None:
    indir = tmp_path / "in"
    indir.mkdir()
    _tone_file(indir / "take.wav")
    soundfile.write(indir / "take.flac", segments(SR, (0.5, 200, 0.5), (0.5, 0, 0)), SR)
    _tone_file(indir / "other.wav")
    out = tmp_path / "out"
    summary = run_batch(indir, out, options=BatchOptions(conditions=("none",), seeds=1))
    folders = {entry["file"]: Path(entry["output"]).name for entry in summary["files"]}
    assert folders == {"other.wav": "other", "take.flac": "take.flac", "take.wav": "take.wav"}
    rerun = run_batch(indir, out, options=BatchOptions(conditions=("none",), seeds=1))
    assert rerun["counts"]["skipped"] == 3
    frames = {json.loads((out / name / "metrics.json").read_text())["frames"] for name in ("take.wav", "take.flac")}
    assert len(frames) == 2  # each folder holds its own recording's results


@pytest.mark.slow
def test_resume_notices_changed_content_and_cleans_what_other_settings_wrote(tmp_path, rng) -> None:
    indir = tmp_path / "in"
    indir.mkdir()
    audio = _tone_file(indir / "a.wav")
    truth_dir = tmp_path / "truth"
    truth_dir.mkdir()
    _head_csv(truth_dir / "a.head.csv", 60, rng)
    out = tmp_path / "out"
    run_batch(indir, out, ground_truth_dir=truth_dir, options=BatchOptions(seeds=1, plots=True))
    assert (out / "a" / "random.fap").exists() and (out / "a" / "report.md").exists()
    # the same path, other content: redone, not "already complete"
    _head_csv(truth_dir / "a.head.csv", 60, rng)
    assert run_batch(indir, out, ground_truth_dir=truth_dir, options=BatchOptions(seeds=1, plots=True))[
        "counts"]["done"] == 1
    soundfile.write(audio, segments(SR, (0.5, 180, 0.5), (1.0, 240, 0.5), (0.5, 0, 0)), SR)
    summary = run_batch(indir, out, ground_truth_dir=truth_dir, options=BatchOptions(seeds=1, plots=True))
    assert summary["counts"]["done"] == 1, summary["files"][0]["error"]
    assert summary["files"][0]["metrics"]["frames"] == 60
    # fewer conditions and no plots: what the earlier run wrote and this one does not is gone
    run_batch(indir, out, ground_truth_dir=truth_dir, options=BatchOptions(conditions=("speech",), seeds=1))
    assert sorted(p.name for p in (out / "a").iterdir()) == ["features.csv", "metrics.json", "speech_driven.fap"]


def test_batch_order_is_natural_and_a_missing_truth_folder_is_refused(tmp_path) -> None:
    indir = tmp_path / "in"
    indir.mkdir()
    for name in ("clip10.wav", "clip2.wav", "clip1.wav"):
        _tone_file(indir / name)
    assert [str(f) for f in find_audio_files(indir)] == ["clip1.wav", "clip2.wav", "clip10.wav"]
    with pytest.raises(ConfigError, match="not a folder"):
        run_batch(indir, tmp_path / "out", ground_truth_dir=tmp_path / "nowhere")


def test_a_worker_that_dies_fails_only_its_own_file(tmp_path, monkeypatch) -> None:
    import multiprocessing

    if multiprocessing.get_start_method() != "fork":
        pytest.skip("the crash is injected into forked workers")
    import prosody.evaluation.compare

    real = prosody.evaluation.compare.compare

    def crashing(audio, **kwargs):
        if Path(audio).name == "crash.wav":
            os._exit(9)  # as the out-of-memory killer would
        return real(audio, **kwargs)

    monkeypatch.setattr(prosody.evaluation.compare, "compare", crashing)
    indir = tmp_path / "in"
    indir.mkdir()
    for name in ("a.wav", "b.wav", "crash.wav", "d.wav", "e.wav"):
        _tone_file(indir / name)
    summary = run_batch(indir, tmp_path / "out", options=BatchOptions(conditions=("none",), seeds=1), jobs=2)
    status = {entry["file"]: entry["status"] for entry in summary["files"]}
    errors = {entry["file"]: entry["error"] for entry in summary["files"]}
    # a file whose worker finished it just before the pool broke is found complete when retried: "skipped"
    assert status.pop("crash.wav") == "failed"
    assert set(status.values()) <= {"done", "skipped"}, errors
    assert all(entry["metrics"] is not None for entry in summary["files"] if entry["file"] != "crash.wav")
    crashed = next(entry for entry in summary["files"] if entry["file"] == "crash.wav")
    assert "worker process died" in crashed["error"]


def test_a_cluster_without_workers_stops_waiting_and_a_lost_scheduler_is_said(monkeypatch) -> None:
    from concurrent.futures import CancelledError, Future

    import prosody.jobs.runner as runner

    monkeypatch.setattr(runner, "NO_WORKER_TIMEOUT_S", 0.2)
    stuck, lost = Future(), Future()
    lost.set_exception(CancelledError())
    results = list(runner.completed_futures({stuck: ("a",), lost: ("b",)}, alive=lambda: False, poll_s=0.05))
    by_task = {task[0]: result for task, result in results}
    assert isinstance(by_task["b"], CancelledError)
    assert isinstance(by_task["a"], runner._NoWorkers) and "no worker" in str(by_task["a"])
    # with workers, a slow file is simply waited for
    slow = Future()
    calls = []

    def alive() -> bool:
        calls.append(1)
        if len(calls) == 3:
            slow.set_result("done")
        return True

    assert list(runner.completed_futures({slow: ("c",)}, alive=alive, poll_s=0.05)) == [(("c",), "done")]


@pytest.mark.slow
def test_sigterm_leaves_no_half_written_file(tmp_path) -> None:
    import signal
    import subprocess
    import sys
    import time

    from prosody.evaluation.preview import find_ffmpeg

    if find_ffmpeg() is None:
        pytest.skip("the MP4 preview, written as it is drawn, needs ffmpeg")
    audio = tmp_path / "long.wav"
    soundfile.write(audio, segments(SR, *[(0.5, 150 + 10 * (k % 7), 0.5) for k in range(240)]), SR)  # 2 min
    out = tmp_path / "out.mp4"
    process = subprocess.Popen([sys.executable, "-m", "prosody", "preview", str(audio), "-o", str(out),
                                "--width", "64"], stderr=subprocess.PIPE)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not any(p.name.endswith(".part.mp4") for p in tmp_path.iterdir()):
        time.sleep(0.02)  # writing has started once the temporary file exists
    process.send_signal(signal.SIGTERM)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 130 and b"interrupted" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["long.wav"]


def test_a_second_comparison_leaves_no_file_of_the_first_behind(tmp_path, speech) -> None:
    out = tmp_path / "out"
    assert main(["compare", str(speech), "-o", str(out), "--seeds", "1", "--lips", "none"]) == 0
    assert (out / "features.png").exists() and (out / "head.png").exists()
    (out / "conditions.mp4").write_bytes(b"an earlier run's video")
    (out / "notes.txt").write_text("the user's own file")
    assert main(["compare", str(speech), "-o", str(out), "--seeds", "1", "--no-plots", "--lips", "none"]) == 0
    assert not (out / "features.png").exists() and not (out / "conditions.mp4").exists()
    assert (out / "notes.txt").read_text() == "the user's own file" and (out / "metrics.json").exists()


def test_head_measures_leave_out_frames_the_recording_lost(rng) -> None:
    from prosody.measures import head_metrics

    fps = 30.0
    t = np.arange(600) / fps
    motion = np.column_stack([np.sin(2 * np.pi * 0.3 * t), np.cos(2 * np.pi * 0.2 * t), np.sin(2 * np.pi * 0.1 * t)])
    recorded = motion * 3000.0
    lost = recorded.copy()
    lost[200:300] = rng.normal(0, 20000, (100, 3))  # what a lost face would put there, were it kept
    measured = np.ones(600, bool)
    measured[200:300] = False
    whole = head_metrics(recorded * 0.5, lost, fps=fps)
    kept = head_metrics(recorded * 0.5, lost, fps=fps, measured=measured)
    assert kept["pitch_r"] == pytest.approx(1.0) and kept["std_ratio"]["49"] == pytest.approx(0.5)
    assert whole["pitch_r"] < 0.9
    assert kept["speed_p50_ratio"] == pytest.approx(0.5, rel=0.05)


def test_typed_metrics_read_a_comparison_losslessly_and_refuse_another_layout(tmp_path, rng) -> None:
    from prosody.evaluation.metrics import METRICS_VERSION, HeadMeasures, Metrics

    audio = _tone_file(tmp_path / "tone.wav")
    truth = _head_csv(tmp_path / "tone.head.csv", 60, rng)
    result = compare(audio, ground_truth=truth, seeds=2, other_head_models={"arx": "arx"})
    measures = result.measures
    speech = result.metrics["conditions"]["SPEECH_DRIVEN"]
    assert measures.conditions["SPEECH_DRIVEN"].head.pitch_r == speech["head"]["pitch_r"] is not None
    assert measures.conditions["SPEECH_DRIVEN"].head.std_ratio["49"] == speech["head"]["std_ratio"]["49"]
    assert measures.controls.head.speed_envelope_r == result.metrics["controls"]["mismatched_audio"]["speed_envelope_r"]
    arx = result.metrics["other_head_models"]["arx"]
    assert measures.other_head_models["arx"]["head"].pitch_r == arx["head"]["pitch_r"]
    assert measures.to_json() == result.metrics  # nothing lost, nothing added
    with pytest.raises(AttributeError, match="no measure 'pitch'"):
        HeadMeasures().pitch  # noqa: B018
    with pytest.raises(ConfigError, match=f"reads version {METRICS_VERSION}"):
        Metrics.from_json({**result.metrics, "version": METRICS_VERSION + 1})


@pytest.mark.slow
def test_batch_takes_a_transcript_beside_each_recording_and_an_expression(tmp_path, capsys) -> None:
    """batch had no --expression and no transcripts: now <stem>.txt beside a recording is its transcript (with
    --transcripts), the same lips as convert --transcript; --expression is convert's; a transcript that changes
    makes the file's output out of date; the refusals come before any file."""
    import shutil

    from conftest import REPO

    from prosody.fap.fapfile import read_fap

    indir = tmp_path / "in"
    indir.mkdir()
    shutil.copy(REPO / "samples" / "arctic_a0009.wav", indir / "a9.wav")
    text = "He turned sharply, and faced Gregson across the table."
    (indir / "a9.txt").write_text(text + "\n")
    out = tmp_path / "out"
    common = ["--condition", "none", "--seeds", "1"]
    assert main(["batch", str(indir), "-o", str(out), *common, "--transcripts", "--expression", "joy:0.5"]) == 0
    capsys.readouterr()
    assert main(["convert", str(indir / "a9.wav"), "-o", str(tmp_path / "c.fap"), "--condition", "none",
                 "--transcript", text, "--expression", "joy:0.5"]) == 0
    batch_lips = read_fap(out / "a9" / "no_prosody.fap").stream
    convert_lips = read_fap(tmp_path / "c.fap").stream
    for fap in (3, 4, 5, 12, 13):  # the lips, and the smile's corners
        assert np.allclose(batch_lips.curve(fap), convert_lips.curve(fap)), fap
    assert main(["batch", str(indir), "-o", str(out), *common, "--transcripts", "--expression", "joy:0.5"]) == 0
    assert "1 already complete" in capsys.readouterr().err
    (indir / "a9.txt").write_text("completely different words about cheese\n")
    assert main(["batch", str(indir), "-o", str(out), *common, "--transcripts", "--expression", "joy:0.5"]) == 0
    assert "1 processed" in capsys.readouterr().err  # the transcript changed: redone
    for bad, said in ((["--expression", "happy"], "unknown expression 'happy'"),
                      (["--language", "es"], "add --transcripts"),
                      (["--transcripts", "--language", "xx"], "does not speak 'xx'"),
                      (["--transcripts", "--lips", "acoustic"], "transcripts are read by the visemes")):
        assert main(["batch", str(indir), "-o", str(tmp_path / "bad"), *common, *bad]) == 2
        assert said in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


def test_compare_takes_converts_gains_and_channels_left_out(tmp_path) -> None:
    """compare had no gains and no --off: they act on the generated conditions (and their controls) as convert
    applies them, the speech-driven condition's stream being convert's with the same settings."""
    from conftest import REPO

    from prosody.evaluation.compare import compare
    from prosody.fap.fapfile import read_fap
    from prosody.motion.conditions import Condition

    speech = REPO / "samples" / "arctic_a0009.wav"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plain = compare(speech, seeds=1, lips=None)
        quiet = compare(speech, seeds=1, lips=None, gains={"yaw": 0.0, "pitch": 0.5}, disabled=["brows"])
    for condition in (Condition.SPEECH_DRIVEN, Condition.RANDOM):
        stream, base = quiet.streams[condition], plain.streams[condition]
        assert not set(range(31, 37)) & set(stream.active_faps)  # the brows left out
        assert np.allclose(stream.curve(49), 0.0) and base.curve(49).std() > 0  # no yaw
        assert np.allclose(stream.curve(50), base.curve(50))  # roll as it was
    assert main(["convert", str(speech), "-o", str(tmp_path / "c.fap"), "--lips", "none", "--yaw-gain", "0",
                 "--pitch-gain", "0.5", "--off", "brows"]) == 0
    converted = read_fap(tmp_path / "c.fap").stream
    for fap in (48, 49, 50):
        assert np.allclose(quiet.streams[Condition.SPEECH_DRIVEN].curve(fap), converted.curve(fap), atol=1.0), fap
    assert main(["compare", str(speech), "-o", str(tmp_path / "cmp"), "--lips", "none", "--seeds", "1",
                 "--no-plots", "--off", "brows", "--yaw-gain", "0"]) == 0
    assert (tmp_path / "cmp" / "speech_driven.fap").is_file()


def test_batch_takes_the_gains_and_channels_left_out(tmp_path, capsys) -> None:
    """batch had no gains and no --off: they are convert's (and compare's), refused alike."""
    import shutil

    from conftest import REPO

    from prosody.fap.fapfile import read_fap

    indir = tmp_path / "in"
    indir.mkdir()
    shutil.copy(REPO / "samples" / "arctic_a0009.wav", indir / "a9.wav")
    out = tmp_path / "out"
    assert main(["batch", str(indir), "-o", str(out), "--condition", "speech", "--seeds", "1", "--lips", "none",
                 "--off", "brows", "--yaw-gain", "0"]) == 0
    stream = read_fap(out / "a9" / "speech_driven.fap").stream
    assert not set(range(31, 37)) & set(stream.active_faps) and np.allclose(stream.curve(49), 0.0)
    assert stream.curve(48).std() > 0
    capsys.readouterr()
    assert main(["batch", str(indir), "-o", str(tmp_path / "bad"), "--off", "ears"]) == 2
    assert "unknown channel(s) 'ears'" in capsys.readouterr().err


def _fails_on_two(value: int) -> int:
    if value == 2:
        raise RuntimeError("two is refused")
    return value * 10


def test_the_job_runner_turns_a_worker_error_into_that_tasks_failure() -> None:
    """Both the batch and the tracker run their tasks through one runner: in worker processes, a task that
    raises gives its own failed outcome, and the others their results."""
    from prosody.jobs.runner import run_tasks

    results = dict(run_tasks(_fails_on_two, [(1,), (2,), (3,)], failed=lambda task, why: f"failed: {why}", jobs=2))
    assert results[(1,)] == 10 and results[(3,)] == 30
    assert results[(2,)] == "failed: worker failed: RuntimeError: two is refused"
    in_process = dict(run_tasks(abs, [(-1,), (4,)], failed=lambda task, why: None))
    assert in_process == {(-1,): 1, (4,): 4}
