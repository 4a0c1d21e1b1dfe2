"""Perceptual-study support: plans, and ballots whose scores and t statistics are computed by hand."""

from __future__ import annotations

import csv
import itertools
import json
from collections import Counter

import numpy as np
import pytest

from prosody.cli import main
from prosody.errors import BallotError
from prosody.study.ballots import CONDITIONS, analyze_ballots, confusion_matrix, parse_ballots, plan_study

HEADER = "stimulus,subject,left,right,choice\n"


def test_plan_has_every_ordered_pair_balanced_and_spread() -> None:
    rows = plan_study(["s1", "s2", "s3"], seed=4)
    assert [row["order"] for row in rows] == list(range(1, 49))
    for stimulus in ("s1", "s2", "s3"):
        mine = [(row["left"], row["right"]) for row in rows if row["stimulus"] == stimulus]
        assert sorted(mine) == sorted(itertools.product(CONDITIONS, CONDITIONS))
        assert Counter(left for left, _ in mine) == Counter({name: 4 for name in CONDITIONS})
        assert Counter(right for _, right in mine) == Counter({name: 4 for name in CONDITIONS})
        positions = [row["order"] for row in rows if row["stimulus"] == stimulus]
        assert max(b - a for a, b in itertools.pairwise(positions)) <= 2 * 3 - 1  # one per round of three
    assert all(a["stimulus"] != b["stimulus"] for a, b in itertools.pairwise(rows))
    assert plan_study(["s1", "s2", "s3"], seed=4) == rows
    assert plan_study(["s1", "s2", "s3"], seed=5) != rows


def test_plan_cli(tmp_path) -> None:
    out = tmp_path / "plan.csv"
    assert main(["study", "plan", "--stimuli", "greeting,story", "--seed", "2", "-o", str(out)]) == 0
    with out.open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert list(rows[0]) == ["order", "stimulus", "left", "right"] and len(rows) == 32


def _ballots(choices: dict[str, dict[tuple[str, str], str]]) -> str:
    lines = [HEADER]
    for subject, answers in choices.items():
        for (left, right), choice in answers.items():
            lines.append(f"clip,{subject},{left},{right},{choice}\n")
    return "".join(lines)


def test_scores_and_t_tests_by_hand() -> None:
    # Three subjects judge all 16 pairs of one stimulus. Subject k always picks SPEECH_DRIVEN when shown,
    # otherwise the left panel, except that subject s3 picks the right panel in the RANDOM/NO_PROSODY pairs.
    def answer(subject: str, left: str, right: str) -> str:
        if "SPEECH_DRIVEN" in (left, right):
            return "left" if left == "SPEECH_DRIVEN" else "right"
        if subject == "s3" and {left, right} == {"RANDOM", "NO_PROSODY"}:
            return "right"
        return "left"

    pairs = list(itertools.product(CONDITIONS, CONDITIONS))
    choices = {s: {(left, right): answer(s, left, right) for left, right in pairs} for s in ("s1", "s2", "s3")}
    results = analyze_ballots(parse_ballots(_ballots(choices)))
    # Per subject, SPEECH_DRIVEN wins its 7 pairs (6 mixed + 1 self). Of the 9 pairs without it the left
    # one wins, and each other condition is on the left in 3 of them: 3 points each. s3's two flipped
    # answers move one point from RANDOM to NO_PROSODY and one back: still 3 and 3.
    assert results["scores"] == {"clip": {"NO_PROSODY": 9, "RANDOM": 9, "SPEECH_DRIVEN": 21, "GROUND_TRUTH": 9}}
    tests = {(t["a"], t["b"]): t for t in results["ttests"]}
    assert list(tests) == [("NO_PROSODY", "RANDOM"), ("NO_PROSODY", "SPEECH_DRIVEN"),
                           ("NO_PROSODY", "GROUND_TRUTH"), ("RANDOM", "SPEECH_DRIVEN"),
                           ("RANDOM", "GROUND_TRUTH"), ("SPEECH_DRIVEN", "GROUND_TRUTH")]
    # every subject: NO_PROSODY 3 - SPEECH_DRIVEN 7 = -4, no spread: t undefined
    constant = tests[("NO_PROSODY", "SPEECH_DRIVEN")]
    assert (constant["mean"], constant["sd"], constant["se"], constant["df"]) == (-4.0, 0.0, 0.0, 2)
    assert constant["t"] is None and constant["p"] is None


def test_t_test_values_against_hand_computation() -> None:
    # subjects' SPEECH_DRIVEN - RANDOM differences of 2, 4 and 6 points (built from partial ballots)
    rows = [HEADER]
    wins = {"s1": 3, "s2": 5, "s3": 7}  # SPEECH_DRIVEN wins, RANDOM wins 1 each
    for subject, count in wins.items():
        others = [name for name in CONDITIONS if name != "SPEECH_DRIVEN"]
        pairs = [("SPEECH_DRIVEN", name) for name in CONDITIONS] + [(name, "SPEECH_DRIVEN") for name in others]
        for left, right in pairs[:count]:
            rows.append(f"clip,{subject},{left},{right},{'left' if left == 'SPEECH_DRIVEN' else 'right'}\n")
        rows.append(f"clip,{subject},RANDOM,GROUND_TRUTH,left\n")
    results = analyze_ballots(parse_ballots("".join(rows)))
    test = next(t for t in results["ttests"] if (t["a"], t["b"]) == ("RANDOM", "SPEECH_DRIVEN"))
    # differences -2, -4, -6: mean -4, sd 2, se 2/sqrt(3), t = -2*sqrt(3), df 2
    assert test["mean"] == pytest.approx(-4.0)
    assert test["sd"] == pytest.approx(2.0)
    assert test["se"] == pytest.approx(2 / 3**0.5)
    assert test["t"] == pytest.approx(-2 * 3**0.5)
    assert test["df"] == 2
    # t quantile 0.975 with 2 df is 4.302653; two-tailed p for |t| = 3.4641 with 2 df is 0.074180
    assert test["ci_low"] == pytest.approx(-4 - 4.302653 * 2 / 3**0.5, abs=1e-5)
    assert test["ci_high"] == pytest.approx(-4 + 4.302653 * 2 / 3**0.5, abs=1e-5)
    assert test["p"] == pytest.approx(0.074180, abs=1e-5)


def test_confusion_matrix_counts_choices_against_the_other_panel() -> None:
    text = HEADER + "c,s,RANDOM,SPEECH_DRIVEN,right\nc,s,SPEECH_DRIVEN,RANDOM,left\nc,s,RANDOM,RANDOM,left\n"
    matrix = confusion_matrix(parse_ballots(text), "c")
    r, s = CONDITIONS.index("RANDOM"), CONDITIONS.index("SPEECH_DRIVEN")
    assert matrix[s, r] == 2 and matrix[r, s] == 0 and matrix[r, r] == 1 and matrix.sum() == 3


def test_bad_ballots_are_reported_by_row(tmp_path, capsys) -> None:
    text = (HEADER + "c,s1,RANDOM,NO_PROSODY,left\n"
            "c,s1,RANDOM,LOUD,left\n"          # line 3: unknown condition
            "c,s1,RANDOM,NO_PROSODY,right\n"   # line 4: duplicate of line 2
            "c,,RANDOM,NO_PROSODY,right\n"     # line 5: incomplete
            "c,s2,RANDOM,NO_PROSODY,middle\n")  # line 6: bad choice
    with pytest.raises(BallotError) as caught:
        parse_ballots(text, source="b.csv")
    message = str(caught.value)
    for expected in ("row 3 names unknown", "'LOUD'", "row 4 duplicates row 2", "row 5 is incomplete (no subject)",
                     "row 6 has choice 'middle'"):
        assert expected in message
    path = tmp_path / "b.csv"
    path.write_text(text)
    out = tmp_path / "r.json"
    assert main(["study", "analyze", str(path), "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(path) in err and not out.exists()
    with pytest.raises(BallotError, match="lacks choice"):
        parse_ballots("stimulus,subject,left,right\n")


def test_analyze_cli_writes_exact_shape_and_report(tmp_path, capsys) -> None:
    pairs = list(itertools.product(CONDITIONS, CONDITIONS))
    lines = [HEADER] + [f"clip,{s},{left},{right},left\n" for s in ("a", "b") for left, right in pairs]
    lines.append("other,a,RANDOM,GROUND_TRUTH,right\n")  # an incomplete subject: a warning, not an error
    path = tmp_path / "ballots.csv"
    path.write_text("".join(lines))
    out, report = tmp_path / "results.json", tmp_path / "report.md"
    assert main(["study", "analyze", str(path), "-o", str(out), "--report", str(report)]) == 0
    assert "judged 1 of 16 pairs of other" in capsys.readouterr().err
    results = json.loads(out.read_text())
    assert set(results) == {"scores", "ttests"}
    assert results["scores"]["clip"] == {name: 8 for name in CONDITIONS}  # always left: 4 lefts x 2 subjects
    assert len(results["ttests"]) == 12
    for test in results["ttests"]:
        assert set(test) == {"stimulus", "a", "b", "mean", "sd", "se", "ci_low", "ci_high", "t", "df", "p", "p_holm"}
    text = report.read_text()
    assert "## clip" in text and "| SPEECH_DRIVEN | 8 |" in text


def test_holm_agrees_with_statsmodels(rng) -> None:
    from statsmodels.stats.multitest import multipletests

    from prosody.study.ballots import holm

    for size in (1, 2, 6, 13):
        p_values = rng.uniform(0, 0.2, size) ** 2
        p_values[0] = p_values[-1]  # ties too
        np.testing.assert_allclose(holm(p_values), multipletests(p_values, method="holm")[1], rtol=1e-12)


def test_vectorised_t_tests_equal_one_at_a_time(rng) -> None:
    from scipy import stats

    from prosody.study.ballots import paired_t_tests

    a, b = rng.integers(0, 5, (12, 7)).astype(float), rng.integers(0, 5, (12, 7)).astype(float)
    b[:, 3] = a[:, 3]  # no difference at all: undefined
    for k, result in enumerate(paired_t_tests(a, b)):
        if k == 3:
            assert result["t"] is None and result["p"] is None and result["sd"] == 0
            continue
        single = stats.ttest_rel(a[:, k], b[:, k])
        assert result["t"] == pytest.approx(single.statistic) and result["p"] == pytest.approx(single.pvalue)


def test_holm_correction_by_hand() -> None:
    from prosody.study.ballots import _add_holm

    # Holm: sort p ascending, multiply the k-th smallest by (m - k + 1), keep the running maximum, cap at 1
    tests = [{"stimulus": "s", "p": p} for p in (0.04, 0.01, 0.03, None)] + [{"stimulus": "t", "p": 0.2}]
    _add_holm(tests)
    assert [t["p_holm"] for t in tests[:3]] == pytest.approx([0.06, 0.03, 0.06])  # 0.01*3, 0.03*2, max(.04, .06)
    assert tests[3]["p_holm"] is None and tests[4]["p_holm"] == pytest.approx(0.2)  # its own family of one


def test_plan_leaves_out_recorded_motion_the_recordings_lack(tmp_path, capsys) -> None:
    """study plan --stimuli FOLDER offered GROUND_TRUTH though no recording had a head.csv; only study stimuli
    failed then."""
    import shutil

    from conftest import REPO

    folder = tmp_path / "recordings"
    folder.mkdir()
    for name in ("a", "b"):
        shutil.copy(REPO / "samples" / "arctic_a0009.wav", folder / f"{name}.wav")
    assert main(["study", "plan", "--stimuli", str(folder), "-o", str(tmp_path / "plan.csv")]) == 0
    assert "GROUND_TRUTH" not in (tmp_path / "plan.csv").read_text()
    assert "a, b lack(s) recorded motion" in capsys.readouterr().err
    assert main(["study", "plan", "--stimuli", str(folder), "--conditions", "none,truth", "-o",
                 str(tmp_path / "asked.csv")]) == 2
    assert "which a, b lack(s)" in capsys.readouterr().err and not (tmp_path / "asked.csv").exists()
    for name in ("a", "b"):
        (folder / f"{name}.head.csv").write_text("frame,rx_rad,ry_rad,rz_rad\n0,0,0,0\n")
    assert main(["study", "plan", "--stimuli", str(folder), "-o", str(tmp_path / "full.csv")]) == 0
    assert "GROUND_TRUTH" in (tmp_path / "full.csv").read_text()
