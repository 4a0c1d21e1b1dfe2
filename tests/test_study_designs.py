"""Study designs beyond paired comparisons: plans, per-participant orders, opinion-score and identification
analyses checked against hand computation, statsmodels and scipy."""

from __future__ import annotations

import itertools
import json
from collections import Counter

import numpy as np
import pytest

from prosody.cli import main
from prosody.errors import BallotError, ConfigError
from prosody.study.ballots import CONDITIONS, plan_study, write_plan
from prosody.study.designs import make_plan, parse_plan, participant_trials
from prosody.study.ratings import (
    analyze_identifications,
    analyze_ratings,
    ballot_design,
    parse_identifications,
    parse_ratings,
    ratings_markdown,
)


def _plan_text(rows) -> str:
    columns = list(rows[0])
    return ",".join(columns) + "\n" + "".join(",".join(str(row[c]) for c in columns) + "\n" for row in rows)


# plans ------------------------------------------------------------------------------------------------------------


def test_paired_plan_of_the_default_design_is_unchanged() -> None:
    assert make_plan(["a", "b"], seed=7) == plan_study(["a", "b"], seed=7)
    assert list(make_plan(["a"], seed=0)[0]) == ["order", "stimulus", "left", "right"]


def test_mos_plan_shows_every_condition_of_every_stimulus_in_rounds() -> None:
    rows = make_plan(["s1", "s2", "s3"], design="mos", conditions=["none", "speech", "calm"], seed=2, repeats=2)
    assert list(rows[0]) == ["order", "stimulus", "condition"] and len(rows) == 3 * 3 * 2
    assert Counter((row["stimulus"], row["condition"]) for row in rows) == {
        (s, c): 2 for s in ("s1", "s2", "s3") for c in ("NO_PROSODY", "SPEECH_DRIVEN", "calm")}
    for k in range(6):  # round k shows each stimulus once
        assert sorted(row["stimulus"] for row in rows[3 * k: 3 * k + 3]) == ["s1", "s2", "s3"]
    assert all(a["stimulus"] != b["stimulus"] for a, b in itertools.pairwise(rows))


def test_identification_needs_its_conditions_and_plans_read_back() -> None:
    with pytest.raises(ConfigError, match="needs its conditions"):
        make_plan(["a"], design="identification")
    with pytest.raises(ConfigError, match="two or more"):
        make_plan(["a"], design="mos", conditions=["speech"])
    with pytest.raises(ConfigError, match="must be 1-64"):
        make_plan(["a"], design="mos", conditions=["speech", "no good"])
    with pytest.raises(ConfigError, match="name files"):
        make_plan(["../a"], design="mos", conditions=["speech", "none"])
    rows = make_plan(["a", "b"], design="identification", conditions=["joy", "anger", "none"], seed=1)
    plan = parse_plan(_plan_text(rows))
    assert plan.design == "identification" and plan.rows == rows
    assert plan.conditions == ("NO_PROSODY", "anger", "joy")  # the thesis's names first, then by name
    assert plan.stimuli == (rows[0]["stimulus"], rows[1]["stimulus"])


def test_bad_plans_are_refused_with_their_line() -> None:
    with pytest.raises(BallotError, match="not a study plan"):
        parse_plan("order,stimulus,score\n1,a,3\n")
    with pytest.raises(BallotError, match="must count 1, 2"):
        parse_plan("order,stimulus,condition\n1,a,none\n3,a,speech\n")
    with pytest.raises(BallotError, match="line 3: 2 cells"):
        parse_plan("order,stimulus,condition\n1,a,none\n2,a\n")
    with pytest.raises(BallotError, match="no trials"):
        parse_plan("order,stimulus,condition\n")


def test_each_participant_sees_every_trial_in_an_order_of_their_own() -> None:
    plan = parse_plan(_plan_text(plan_study(["a", "b", "c"], seed=5)))
    first = participant_trials(plan, 1)
    assert first == list(plan.trials)  # the first participant: the plan as written
    orders = []
    for ordinal in range(2, 7):
        mine = participant_trials(plan, ordinal)
        assert mine == participant_trials(plan, ordinal)  # the same number, the same order
        assert sorted(t.order for t in mine) == list(range(1, 49))
        assert all(a.stimulus != b.stimulus for a, b in itertools.pairwise(mine))
        swapped = ordinal % 2 == 0
        for trial in mine:
            original = plan.trials[trial.order - 1]
            assert trial.stimulus == original.stimulus
            assert trial.conditions == (original.conditions[::-1] if swapped else original.conditions)
        orders.append(tuple(t.order for t in mine))
    assert len(set(orders)) == 5


# opinion scores ---------------------------------------------------------------------------------------------------


def _ratings_text(rows) -> str:
    return "stimulus,subject,condition,score\n" + "".join(f"{s},{u},{c},{v}\n" for s, u, c, v in rows)


def test_one_way_anova_by_hand() -> None:
    # groups (1,2,3), (2,3,4), (4,5,5): means 2, 3, 14/3; SSB = 882/81, SSW = 14/3, F(2, 6) = 7 exactly
    rows = [("clip", f"s{k}", c, v) for c, values in (("NO_PROSODY", (1, 2, 3)), ("RANDOM", (2, 3, 4)),
                                                       ("SPEECH_DRIVEN", (4, 5, 5)))
            for k, v in enumerate(values)]
    results = analyze_ratings(parse_ratings(_ratings_text(rows)), CONDITIONS[:3])
    anova = results["anova"]
    assert anova["F"] == pytest.approx(7.0) and (anova["df_between"], anova["df_within"]) == (2, 6)
    assert anova["eta_squared"] == pytest.approx((882 / 81) / (882 / 81 + 14 / 3))
    from scipy import stats

    assert anova["p"] == pytest.approx(stats.f.sf(7.0, 2, 6))
    mean = results["conditions"]["SPEECH_DRIVEN"]
    assert mean["mean"] == pytest.approx(14 / 3) and mean["sd"] == pytest.approx((1 / 3) ** 0.5)
    half = stats.t.ppf(0.975, 2) * (1 / 3) ** 0.5 / 3 ** 0.5
    assert (mean["ci_low"], mean["ci_high"]) == pytest.approx((14 / 3 - half, 14 / 3 + half))
    # each subject rated each condition once: repeated measures over 3 subjects
    rm = results["anova_rm"]
    assert (rm["subjects"], rm["df_condition"], rm["df_error"]) == (3, 2, 4)
    # subject means 7/3, 10/3, 4: SS_subject = 3 * sum((m - 29/9)^2) = 342/81, SS_error = 14/3 - 342/81 = 36/81,
    # F(2, 4) = (882/81 / 2) / (36/81 / 4) = 49
    assert rm["F"] == pytest.approx(49.0) and rm["p"] == pytest.approx(stats.f.sf(49.0, 2, 4))
    assert rm["partial_eta_squared"] == pytest.approx(882 / (882 + 36))
    tukey = {(t["a"], t["b"]): t for t in results["tukey"]}
    assert tukey[("NO_PROSODY", "SPEECH_DRIVEN")]["mean_difference"] == pytest.approx(2 - 14 / 3)
    # Cohen's d with the pooled sd of (1,2,3) and (4,5,5): sqrt((2 + 2/3) / 4)
    assert tukey[("NO_PROSODY", "SPEECH_DRIVEN")]["cohen_d"] == pytest.approx((2 - 14 / 3) / ((8 / 3) / 4) ** 0.5)


def test_anovas_and_tukey_agree_with_statsmodels_and_scipy(rng) -> None:
    import pandas as pd
    from scipy import stats
    from statsmodels.stats.anova import AnovaRM
    from statsmodels.stats.multicomp import pairwise_tukeyhsd

    conditions = ["NO_PROSODY", "RANDOM", "SPEECH_DRIVEN", "calm"]
    effect = {"NO_PROSODY": 2.2, "RANDOM": 2.8, "SPEECH_DRIVEN": 3.6, "calm": 3.3}
    rows = []
    for subject in range(12):
        bias = rng.normal(0, 0.5)
        for stimulus in ("a", "b"):
            for name in conditions:
                rows.append((stimulus, f"p{subject}", name,
                             int(np.clip(np.round(effect[name] + bias + rng.normal(0, 0.8)), 1, 5))))
    rows.append(("a", "late", "RANDOM", 3))  # a subject who rated one condition: left out of the RM ANOVA only
    results = analyze_ratings(parse_ratings(_ratings_text(rows)), conditions)
    frame = pd.DataFrame(rows, columns=["stimulus", "subject", "condition", "score"])
    groups = [frame.loc[frame.condition == name, "score"].to_numpy(float) for name in conditions]
    expected = stats.f_oneway(*groups)
    assert results["anova"]["F"] == pytest.approx(expected.statistic)
    assert results["anova"]["p"] == pytest.approx(expected.pvalue)
    assert (results["anova"]["df_between"], results["anova"]["df_within"]) == (3, len(rows) - 4)
    complete = frame[frame.subject != "late"]
    table = AnovaRM(complete, "score", "subject", within=["condition"], aggregate_func="mean").fit().anova_table
    rm = results["anova_rm"]
    assert rm["F"] == pytest.approx(float(table["F Value"].iloc[0]))
    assert rm["p"] == pytest.approx(float(table["Pr > F"].iloc[0]))
    assert (rm["subjects"], rm["subjects_left_out"], rm["df_error"]) == (12, 1, 33)
    # partial eta squared from F: F*df1 / (F*df1 + df2)
    f = rm["F"]
    assert rm["partial_eta_squared"] == pytest.approx(f * 3 / (f * 3 + 33))
    tukey = pairwise_tukeyhsd(frame["score"].to_numpy(float), frame["condition"].to_numpy(str))
    groups_sorted = list(tukey.groupsunique)
    for test in results["tukey"]:
        i, j = groups_sorted.index(test["a"]), groups_sorted.index(test["b"])
        k = list(itertools.combinations(range(4), 2)).index((min(i, j), max(i, j)))
        assert test["p_adjusted"] == pytest.approx(float(tukey.pvalues[k]))
        sign = -1 if i < j else 1  # statsmodels gives the later group minus the earlier one
        assert test["mean_difference"] == pytest.approx(sign * float(tukey.meandiffs[k]))
        assert test["ci_low"] <= test["mean_difference"] <= test["ci_high"]


def _rows(scores: dict[str, list[int]], subjects: int = 6) -> list[tuple]:
    """Each subject rates each condition with the scores given for it, in turn (two stimuli)."""
    return [(stimulus, f"p{subject}", name, values[(subject * 2 + k) % len(values)])
            for subject in range(subjects) for k, stimulus in enumerate(("a", "b")) for name, values in scores.items()]


@pytest.mark.parametrize("score", [1, 3, 4, 5])
@pytest.mark.parametrize("subjects", [2, 7, 13])
def test_scores_that_are_all_equal_are_no_effect(score, subjects) -> None:
    import warnings

    from scipy import stats

    rows = _rows({name: [score] for name in ("NO_PROSODY", "RANDOM", "SPEECH_DRIVEN", "calm")}, subjects)
    results = analyze_ratings(parse_ratings(_ratings_text(rows)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # scipy warns of the constant input, and answers nan
        assert np.isnan(stats.f_oneway(*[[score] * (2 * subjects)] * 4).statistic)
    for anova in (results["anova"], results["anova_rm"]):
        assert anova["F"] is None and anova["p"] is None, anova
        assert "no variance" in anova["note"]
    assert results["anova"]["eta_squared"] is None and results["anova_rm"]["partial_eta_squared"] is None
    assert all(test["p_adjusted"] is None and test["cohen_d"] is None and test["reject"] is None
               for test in results["tukey"])
    assert all(entry["sd"] == 0 for entry in results["conditions"].values())
    assert "no variance, so no effect to test" in ratings_markdown(results)


def test_conditions_each_constant_but_different_leave_f_undefined() -> None:
    rows = _rows({"NO_PROSODY": [2], "SPEECH_DRIVEN": [4]})
    anova = analyze_ratings(parse_ratings(_ratings_text(rows)))["anova"]
    assert anova["F"] is None and anova["p"] is None and anova["eta_squared"] == 1.0
    assert "do not vary within any condition" in anova["note"]


@pytest.mark.parametrize("scores", [
    {"NO_PROSODY": [3, 4], "SPEECH_DRIVEN": [3, 4, 4, 4]},  # two-valued
    {"NO_PROSODY": [3], "RANDOM": [3], "SPEECH_DRIVEN": [3, 4]},  # tied: one condition varies, a little
    {"NO_PROSODY": [1, 5], "RANDOM": [5, 1], "SPEECH_DRIVEN": [5, 5, 1, 1]},  # equal means, the same spread
])
def test_two_valued_and_tied_scores_agree_with_scipy_and_statsmodels(scores) -> None:
    import pandas as pd
    from scipy import stats
    from statsmodels.stats.anova import AnovaRM
    from statsmodels.stats.multicomp import pairwise_tukeyhsd

    rows = _rows(scores)
    results = analyze_ratings(parse_ratings(_ratings_text(rows)))
    frame = pd.DataFrame(rows, columns=["stimulus", "subject", "condition", "score"])
    groups = [frame.loc[frame.condition == name, "score"].to_numpy(float) for name in sorted(scores)]
    expected = stats.f_oneway(*groups)
    assert results["anova"]["F"] == pytest.approx(expected.statistic, abs=1e-12)
    assert results["anova"]["p"] == pytest.approx(expected.pvalue)
    # the repeated-measures error sum of squares in exact fractions: zero where subjects and conditions add up
    from fractions import Fraction

    means = {(subject, name): Fraction(int(group.sum()), len(group))
             for (subject, name), group in frame.groupby(["subject", "condition"])["score"]}
    subjects, names = sorted({k[0] for k in means}), sorted(scores)
    grand = sum(means.values()) / len(means)
    by_subject = {u: sum(means[u, c] for c in names) / len(names) for u in subjects}
    by_condition = {c: sum(means[u, c] for u in subjects) / len(subjects) for c in names}
    error = sum((means[u, c] - by_subject[u] - by_condition[c] + grand) ** 2 for u in subjects for c in names)
    rm = results["anova_rm"]
    if error == 0:  # statsmodels divides by its rounding noise here (F about 1e29 in the tied case)
        assert rm["F"] is None and rm["p"] is None
    else:
        table = AnovaRM(frame, "score", "subject", within=["condition"], aggregate_func="mean").fit().anova_table
        assert rm["F"] == pytest.approx(float(table["F Value"].iloc[0]), abs=1e-9)
    tukey = pairwise_tukeyhsd(frame["score"].to_numpy(float), frame["condition"].to_numpy(str))
    assert sorted(test["p_adjusted"] for test in results["tukey"]) == pytest.approx(sorted(tukey.pvalues))


def test_bad_rating_rows_are_listed() -> None:
    text = ("stimulus,subject,condition,score,order\n"
            "a,p1,speech,6,1\n"       # line 2: off the scale
            "a,p1,loud,3,2\n"         # line 3: unknown with a plan's conditions
            "a,p1,none,3,3\n"
            "a,p1,none,4,3\n")        # line 5: the same trial twice
    with pytest.raises(BallotError) as caught:
        parse_ratings(text, source="r.csv", conditions=("NO_PROSODY", "SPEECH_DRIVEN"))
    message = str(caught.value)
    for expected in ("row 2 has score '6'", "row 3 names unknown condition(s) 'loud'",
                     "row 5 duplicates row 4 (subject p1, trial 3)"):
        assert expected in message


# identification ---------------------------------------------------------------------------------------------------


def test_identification_accuracy_binomial_and_confusion_by_hand() -> None:
    from scipy import stats

    # joy shown 10 times, answered joy 8, calm 2; calm shown 10 times, answered calm 4, joy 3, still 3
    rows = [("joy", "joy")] * 8 + [("joy", "calm")] * 2 + [("calm", "calm")] * 4 + [("calm", "joy")] * 3 \
        + [("calm", "still")] * 3
    text = "stimulus,subject,shown,answer\n" + "".join(f"clip,p{k},{s},{a}\n" for k, (s, a) in enumerate(rows))
    assert ballot_design(text) == "identification"
    results = analyze_identifications(parse_identifications(text), ["joy", "calm", "still"])
    assert results["chance"] == pytest.approx(1 / 3)
    assert results["confusion"] == [[8, 2, 0], [3, 4, 3], [0, 0, 0]]
    joy = results["per_class"]["joy"]
    assert (joy["n"], joy["correct"], joy["accuracy"]) == (10, 8, 0.8)
    assert joy["p"] == pytest.approx(stats.binom.sf(7, 10, 1 / 3))  # P(X >= 8)
    low, high = stats.beta.ppf(0.025, 8, 3), stats.beta.ppf(0.975, 9, 2)  # Clopper-Pearson by its definition
    assert (joy["ci_low"], joy["ci_high"]) == pytest.approx((low, high))
    assert "still" not in results["per_class"]  # never shown
    calm = results["per_class"]["calm"]
    assert calm["p_holm"] == pytest.approx(min(1.0, max(2 * joy["p"], calm["p"])))  # Holm over two classes
    assert results["overall"]["correct"] == 12 and results["overall"]["p"] == pytest.approx(
        stats.binom.sf(11, 20, 1 / 3))


def test_analyze_cli_reads_each_design_and_draws_its_figure(tmp_path, capsys) -> None:
    from PIL import Image

    mos = tmp_path / "mos.csv"
    mos.write_text(_ratings_text([("a", f"p{k}", c, 1 + (k + i) % 5) for k in range(4)
                                  for i, c in enumerate(("none", "speech", "random"))]))
    out, report = tmp_path / "mos.json", tmp_path / "mos.md"
    assert main(["study", "analyze", str(mos), "-o", str(out), "--report", str(report)]) == 0
    results = json.loads(out.read_text())
    assert results["design"] == "mos" and set(results["conditions"]) == {"NO_PROSODY", "SPEECH_DRIVEN", "RANDOM"}
    assert "## One-way ANOVA" in report.read_text() and "mos.means.png" in report.read_text()
    with Image.open(tmp_path / "mos.means.png") as image:
        assert image.size[0] > 300

    ident = tmp_path / "id.csv"
    ident.write_text("stimulus,subject,shown,answer\n" + "".join(
        f"a,p{k},{s},{a}\n" for k, (s, a) in enumerate([("joy", "joy"), ("sad", "joy"), ("sad", "sad")] * 3)))
    plan = tmp_path / "plan.csv"
    write_plan(make_plan(["a"], design="identification", conditions=["joy", "sad"]), plan)
    out, report = tmp_path / "id.json", tmp_path / "id.md"
    assert main(["study", "analyze", str(ident), "--plan", str(plan), "-o", str(out), "--report", str(report)]) == 0
    assert json.loads(out.read_text())["confusion"] == [[3, 0], [3, 3]]
    with Image.open(tmp_path / "id.confusion.png") as image:
        assert image.size[0] > 300
    assert "66.7% correct (chance 50.0%)" in capsys.readouterr().err
    # a ballot of a stimulus the plan does not have
    (tmp_path / "stray.csv").write_text(ident.read_text() + "elsewhere,p1,joy,joy\n")
    assert main(["study", "analyze", str(tmp_path / "stray.csv"), "--plan", str(plan), "-o",
                 str(tmp_path / "x.json")]) == 1
    assert "1 ballot row(s) name a stimulus that is not in" in capsys.readouterr().err
    assert not (tmp_path / "x.json").exists()
    # ballots of one design against a plan of another: one line
    assert main(["study", "analyze", str(mos), "--plan", str(plan), "-o", str(tmp_path / "x.json")]) == 1
    assert "mos ballots, but" in capsys.readouterr().err
    (tmp_path / "junk.csv").write_text("a,b,c\n1,2,3\n")
    assert main(["study", "analyze", str(tmp_path / "junk.csv"), "-o", str(tmp_path / "x.json")]) == 1
    assert "not a ballot file" in capsys.readouterr().err


def test_plan_cli_designs(tmp_path) -> None:
    out = tmp_path / "p.csv"
    assert main(["study", "plan", "--stimuli", "a,b", "--design", "mos", "--conditions", "none,speech",
                 "--repeats", "3", "-o", str(out)]) == 0
    assert out.read_text().splitlines()[0] == "order,stimulus,condition" and len(out.read_text().splitlines()) == 13
    conditions = tmp_path / "mine.json"
    conditions.write_text(json.dumps({"format": "visual-prosody-study-conditions", "version": 1, "conditions": {
        "calm": {"options": "--activation 0.4"}, "lively": {"options": "--spatial 0.5"}}}))
    assert main(["study", "plan", "--stimuli", "a", "--design", "identification", "--conditions",
                 f"none,{conditions}", "-o", str(out)]) == 0
    assert parse_plan(out.read_text()).conditions == ("NO_PROSODY", "calm", "lively")
    assert main(["study", "plan", "--stimuli", "a", "--design", "identification", "-o", str(out)]) == 2
    assert main(["study", "plan", "--stimuli", "a", "--repeats", "2", "-o", str(out)]) == 2


def test_a_ballot_of_many_classes_draws_a_bounded_figure_and_nothing_before_a_failure(tmp_path, capsys) -> None:
    import resource
    import time

    from PIL import Image

    from prosody.study.ratings import MAX_CONFUSION_CLASSES

    classes = [f"c{k:03d}" for k in range(200)]
    rows = [(classes[k], classes[k] if k % 3 else classes[(k + 1) % 200]) for k in range(200)
            for _ in range(1 + (k % 7 == 0) * 5)]  # every seventh class shown six times: those lead the figure
    ident = tmp_path / "many.csv"
    ident.write_text("stimulus,subject,shown,answer\n" + "".join(f"a,p{k % 9},{s},{a}\n"
                                                                  for k, (s, a) in enumerate(rows)))
    out, report = tmp_path / "many.json", tmp_path / "many.md"
    before_s, before_kb = time.process_time(), resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    assert main(["study", "analyze", str(ident), "-o", str(out), "--report", str(report)]) == 0
    grown_mb = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before_kb) / 1024
    assert time.process_time() - before_s < 20 and grown_mb < 400  # 200 classes took 12.9 GB unbounded
    assert len(json.loads(out.read_text())["confusion"]) == 200  # the JSON keeps the whole matrix
    with Image.open(tmp_path / "many.confusion.png") as image:
        assert max(image.size) < 3000
    text = report.read_text()
    assert f"of the {MAX_CONFUSION_CLASSES} classes shown most often (of 200" in text
    table = text.split("Confusion matrix")[1]
    assert all(f"| {classes[k]} |" in table for k in range(0, 140, 7))  # the twenty shown six times
    assert f"| {classes[1]} |" not in table
    # a failure after the analysis (a stimulus the plan lacks) leaves no figure, JSON or report behind
    plan = tmp_path / "plan.csv"
    write_plan(make_plan(["b"], design="identification", conditions=classes), plan)
    for name in ("many.json", "many.md", "many.confusion.png"):
        (tmp_path / name).unlink()
    assert main(["study", "analyze", str(ident), "--plan", str(plan), "-o", str(out), "--report", str(report)]) == 1
    assert "name a stimulus that is not in" in capsys.readouterr().err
    assert sorted(path.name for path in tmp_path.iterdir()) == ["many.csv", "plan.csv"]


@pytest.mark.slow
def test_many_conditions_are_analysed_quickly_without_every_pair() -> None:
    import time

    from prosody.study.ratings import MAX_TUKEY_CONDITIONS

    rows = [("s", f"p{j}", f"c{c:03d}", 1 + (c * 7 + j) % 5) for c in range(500) for j in range(4)]
    started = time.process_time()
    results = analyze_ratings(parse_ratings(_ratings_text(rows)))
    report = ratings_markdown(results)
    assert time.process_time() - started < 15  # every pair's test took a minute
    assert results["tukey"] == [] and results["anova"]["F"] is not None
    assert f"Not run: 500 conditions, more than the {MAX_TUKEY_CONDITIONS}" in report and len(report) < 100_000


def test_a_plan_too_large_to_serve_or_a_stimulus_named_like_the_manifest_is_refused_at_plan_time(tmp_path,
                                                                                                 capsys) -> None:
    stimuli = ",".join(f"s{i}" for i in range(7000))  # 7,000 x 16 ordered pairs: 112,000 trials
    assert main(["study", "plan", "--stimuli", stimuli, "-o", str(tmp_path / "p.csv")]) == 2
    assert "112000 trials, more than the 100000" in capsys.readouterr().err
    assert main(["study", "plan", "--stimuli", "a,stimuli.json", "-o", str(tmp_path / "p.csv")]) == 2
    assert "'stimuli.json' name the stimulus folder's own files" in capsys.readouterr().err
    assert not (tmp_path / "p.csv").exists()
    assert main(["study", "plan", "--stimuli", ",".join(f"s{i}" for i in range(6250)), "-o",
                 str(tmp_path / "p.csv")]) == 0  # exactly 100,000


def test_plan_takes_the_folder_of_recordings_as_stimuli(tmp_path, capsys) -> None:
    recordings = tmp_path / "recordings"
    recordings.mkdir()
    for name in ("b", "a", "c"):
        (recordings / f"{name}.wav").write_bytes(b"RIFF")
    (recordings / "notes.txt").write_text("x")
    assert main(["study", "plan", "--stimuli", str(recordings), "--design", "mos", "-o", str(tmp_path / "p.csv")]) == 0
    assert sorted({row.split(",")[1] for row in (tmp_path / "p.csv").read_text().splitlines()[1:]}) == ["a", "b", "c"]
    (tmp_path / "empty").mkdir()
    assert main(["study", "plan", "--stimuli", str(tmp_path / "empty"), "-o", str(tmp_path / "q.csv")]) == 2
    assert "a folder with no recording" in capsys.readouterr().err


def test_drawing_a_report_figure_leaves_pyplot_and_its_backend_alone(tmp_path) -> None:
    # a notebook user's backend must not be switched by a library call
    import subprocess
    import sys

    code = ("import sys, matplotlib; matplotlib.use('svg'); "
            "from prosody.study.ratings import plot_means; "
            "entry = {'n': 3, 'mean': 3.0, 'sd': 1.0, 'ci_low': 2.0, 'ci_high': 4.0}; "
            f"plot_means({{'conditions': {{'a': entry, 'b': entry}}}}, {str(tmp_path / 'm.png')!r}); "
            "print(matplotlib.get_backend(), 'matplotlib.pyplot' in sys.modules)")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["svg", "False"]
    assert (tmp_path / "m.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
