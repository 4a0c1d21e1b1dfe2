"""Opinion scores (Jia et al. 2013) and identification (Wu et al. 2006): their ballots and analyses.

Opinion-score ballots have the columns ``stimulus,subject,condition,score`` (score a whole number from 1 to 5).
The analysis gives per condition the mean with its 95% interval (t), a one-way ANOVA over all ratings (as seed
000 reports it, F[2,57] for three groups of 20) with eta squared and omega squared, a repeated-measures ANOVA
over the subjects who rated every condition (their ratings averaged over stimuli; partial eta squared), and
Tukey's pairwise tests with Cohen's d (statsmodels: ``anova_lm``, ``AnovaRM``, ``pairwise_tukeyhsd``).

Identification ballots have the columns ``stimulus,subject,shown,answer``. The analysis gives the accuracy per
shown class with its exact (Clopper-Pearson) 95% interval and a one-sided binomial test against chance (one over
the number of classes; Holm-corrected over the classes), the overall accuracy, and the confusion matrix (rows:
shown; columns: answered).

A ballot file with an ``order`` column (as ``prosody study export`` writes) may hold one answer per subject and
trial number; without it, one per subject, stimulus and condition for opinion scores.
"""

from __future__ import annotations

import csv
import io
import itertools
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import BallotError, require_extra
from .ballots import BALLOT_COLUMNS, SHORT_NAMES, ballot_error, filled_rows, holm

MOS_COLUMNS = ("stimulus", "subject", "condition", "score")
IDENTIFICATION_COLUMNS = ("stimulus", "subject", "shown", "answer")
#: The opinion scale: 1 (bad) to 5 (excellent), as Jia et al.'s questionnaire.
SCORES = (1, 2, 3, 4, 5)
SCORE_LABELS = {1: "bad", 2: "poor", 3: "fair", 4: "good", 5: "excellent"}


@dataclass(frozen=True)
class Rating:
    row: int
    stimulus: str
    subject: str
    condition: str
    score: int


@dataclass(frozen=True)
class Identification:
    row: int
    stimulus: str
    subject: str
    shown: str
    answer: str

    @property
    def correct(self) -> bool:
        return self.shown == self.answer


def ballot_design(text: str) -> str:
    """``paired``, ``mos`` or ``identification``, from the columns of a ballot file's first line."""
    try:
        header = next(csv.reader(io.StringIO(text)), [])
    except csv.Error:
        header = []
    columns = {cell.strip().lower() for cell in header}
    for design, needed in (("paired", BALLOT_COLUMNS), ("mos", MOS_COLUMNS),
                           ("identification", IDENTIFICATION_COLUMNS)):
        if set(needed) <= columns:
            return design
    raise BallotError(f"not a ballot file: its columns {','.join(header) or '(none)'} are none of "
                      f"{','.join(BALLOT_COLUMNS)} (paired), {','.join(MOS_COLUMNS)} (mos) or "
                      f"{','.join(IDENTIFICATION_COLUMNS)} (identification)")


def _check_names(line: int, values: dict, columns: Sequence[str], allowed: Sequence[str] | None,
                 problems: list[str]) -> bool:
    for column in columns:
        values[column] = SHORT_NAMES.get(values[column].lower(), values[column])
    if allowed is None:
        return True
    unknown = [values[column] for column in columns if values[column] not in allowed]
    if unknown:
        problems.append(f"row {line} names unknown condition(s) {', '.join(map(repr, unknown))} "
                        f"(expected {', '.join(allowed)})")
        return False
    return True


def _check_repeat(line: int, values: dict, key: tuple, seen: dict, problems: list[str]) -> bool:
    if "order" in values:
        key = (values["subject"], values["order"])
    if key in seen:
        problems.append(f"row {line} duplicates row {seen[key]} (subject {values['subject']}"
                        + (f", trial {values['order']})" if "order" in values else f", {key[0]}, {key[2]})"))
        return False
    seen[key] = line
    return True


def parse_ratings(text: str, *, source: str = "<ballots>", conditions: Sequence[str] | None = None) -> list[Rating]:
    """Opinion-score ballots (columns ``stimulus,subject,condition,score``); every bad row is listed by line.

    ``conditions``: the names a ballot may give (a plan's); any name when None.
    """
    records, problems = filled_rows(text, source, MOS_COLUMNS, ("order",))
    ratings: list[Rating] = []
    seen: dict[tuple, int] = {}
    for line, values in records:
        if not _check_names(line, values, ("condition",), conditions, problems):
            continue
        try:
            score = int(values["score"])
        except ValueError:
            score = 0
        if score not in SCORES:
            problems.append(f"row {line} has score {values['score']!r} (expected a whole number from 1 to 5)")
            continue
        key = (values["stimulus"], values["subject"], values["condition"])
        if not _check_repeat(line, values, key, seen, problems):
            continue
        ratings.append(Rating(line, values["stimulus"], values["subject"], values["condition"], score))
    if problems:
        raise ballot_error(source, problems)
    if not ratings:
        raise BallotError(f"{source}: no ballot rows")
    return ratings


def parse_identifications(text: str, *, source: str = "<ballots>",
                          classes: Sequence[str] | None = None) -> list[Identification]:
    """Identification ballots (columns ``stimulus,subject,shown,answer``); every bad row is listed by line.

    ``classes``: the names shown and answered (a plan's conditions); any name when None.
    """
    records, problems = filled_rows(text, source, IDENTIFICATION_COLUMNS, ("order",))
    answers: list[Identification] = []
    seen: dict[tuple, int] = {}
    for line, values in records:
        if not _check_names(line, values, ("shown", "answer"), classes, problems):
            continue
        if "order" in values and not _check_repeat(line, values, (), seen, problems):
            continue
        answers.append(Identification(line, values["stimulus"], values["subject"], values["shown"],
                                      values["answer"]))
    if problems:
        raise ballot_error(source, problems)
    if not answers:
        raise BallotError(f"{source}: no ballot rows")
    return answers


# ---------------------------------------------------------------------------------------------------------------
# opinion scores


def _condition_order(names: Sequence[str], conditions: Sequence[str] | None) -> list[str]:
    present = set(names)
    if conditions is not None:
        return [name for name in conditions if name in present]
    return list(dict.fromkeys(sorted(present)))


def _mean_interval(values: np.ndarray) -> dict:
    from scipy import stats

    n = values.size
    mean = float(values.mean())
    sd = float(values.std(ddof=1)) if _varies(values) else 0.0
    half = float(stats.t.ppf(0.975, n - 1) * sd / math.sqrt(n)) if n > 1 else None
    return {"n": int(n), "mean": mean, "sd": sd, "ci_low": None if half is None else mean - half,
            "ci_high": None if half is None else mean + half}


def _varies(values: np.ndarray) -> bool:
    """Whether the values differ at all: exactly, by their range (a mean-based spread of equal floats can be
    rounding noise that a test would call an effect)."""
    return values.size > 1 and float(np.ptp(values)) > 0


def _cohen_d(a: np.ndarray, b: np.ndarray) -> float | None:
    if a.size + b.size <= 2 or not (_varies(a) or _varies(b)):
        return None
    pooled = ((a.size - 1) * a.var(ddof=1 if a.size > 1 else 0) + (b.size - 1) * b.var(ddof=1 if b.size > 1 else 0)) \
        / (a.size + b.size - 2)
    return float((a.mean() - b.mean()) / math.sqrt(pooled)) if pooled > 0 else None


#: Why F and p are absent where the scores leave nothing to test.
NO_SPREAD = "every score is the same: there is no variance, so no effect to test"
NO_SPREAD_WITHIN = "the scores do not vary within any condition: F is undefined"


def _one_way(frame) -> dict:
    from statsmodels.formula.api import ols
    from statsmodels.stats.anova import anova_lm

    groups = frame["condition"].nunique()
    if groups < 2 or len(frame) <= groups:
        return {"skipped": f"needs two or more conditions and more ratings than conditions ({len(frame)} ratings "
                           f"of {groups} condition(s))"}
    table = anova_lm(ols("score ~ C(condition)", data=frame).fit())
    between, within = table.loc["C(condition)"], table.loc["Residual"]
    result = {"F": None, "df_between": int(between["df"]), "df_within": int(within["df"]), "p": None,
              "eta_squared": None, "omega_squared": None}
    scores = frame["score"].to_numpy(float)
    if not _varies(scores):
        return result | {"note": NO_SPREAD}
    if not any(_varies(group.to_numpy(float)) for _, group in frame.groupby("condition")["score"]):
        # every condition constant, not all alike: the conditions explain everything, F has no error to divide by
        return result | {"eta_squared": 1.0, "note": NO_SPREAD_WITHIN}
    total = between["sum_sq"] + within["sum_sq"]
    mean_square_within = within["sum_sq"] / within["df"]
    return result | {"F": float(between["F"]), "p": float(between["PR(>F)"]),
                     "eta_squared": float(between["sum_sq"] / total),
                     "omega_squared": float((between["sum_sq"] - between["df"] * mean_square_within)
                                            / (total + mean_square_within))}


def _repeated(frame, conditions: list[str]) -> dict:
    from statsmodels.stats.anova import AnovaRM

    means = frame.groupby(["subject", "condition"], sort=False)["score"].mean().unstack()
    complete = means.reindex(columns=conditions).dropna()
    dropped = len(means) - len(complete)
    if len(complete) < 2 or len(conditions) < 2:
        return {"skipped": f"needs two or more subjects who rated every condition ({len(complete)} did)"}
    matrix = complete.to_numpy(float)
    n, k = matrix.shape
    if not _varies(matrix.ravel()):
        return {"subjects": n, "subjects_left_out": dropped, "df_condition": k - 1, "df_error": (n - 1) * (k - 1),
                "F": None, "p": None, "partial_eta_squared": None, "note": NO_SPREAD}
    grand = matrix.mean()
    ss_condition = n * float(((matrix.mean(axis=0) - grand) ** 2).sum())
    ss_subject = k * float(((matrix.mean(axis=1) - grand) ** 2).sum())
    ss_error = float(((matrix - grand) ** 2).sum()) - ss_condition - ss_subject
    result = {"subjects": n, "subjects_left_out": dropped, "df_condition": k - 1, "df_error": (n - 1) * (k - 1),
              "F": None, "p": None,
              "partial_eta_squared": ss_condition / (ss_condition + ss_error) if ss_condition + ss_error > 0
              else None}
    if ss_error > 1e-12 * max(1.0, ss_condition):
        long = complete.stack().rename("score").reset_index()
        table = AnovaRM(long, depvar="score", subject="subject", within=["condition"]).fit().anova_table
        result["F"] = float(table["F Value"].iloc[0])
        result["p"] = float(table["Pr > F"].iloc[0])
    else:
        result["note"] = "subjects and conditions add up to every mean exactly: no error variance, F is undefined"
    return result


#: Most conditions whose every pair Tukey's test compares: 435 pairs (statsmodels integrates the studentized
#: range once per pair; 500 conditions, 124,750 pairs, took a minute and a 7 MB report).
MAX_TUKEY_CONDITIONS = 30


def _tukey(frame, conditions: list[str]) -> list[dict]:
    from statsmodels.stats.multicomp import pairwise_tukeyhsd

    if len(conditions) < 2 or len(frame) <= len(conditions) or len(conditions) > MAX_TUKEY_CONDITIONS:
        return []
    scores = {name: frame.loc[frame["condition"] == name, "score"].to_numpy(float) for name in conditions}
    spread = any(_varies(values) for values in scores.values())
    result = pairwise_tukeyhsd(frame["score"].to_numpy(float), frame["condition"].to_numpy(str)) if spread else None
    tests = []
    if result is not None:  # statsmodels' pairs are in combinations order of its sorted groups
        groups = {name: i for i, name in enumerate(result.groupsunique)}
        pair_index = {pair: k for k, pair in enumerate(itertools.combinations(range(len(groups)), 2))}
    for a, b in itertools.combinations(conditions, 2):
        entry = {"a": a, "b": b, "mean_difference": float(scores[a].mean() - scores[b].mean()),
                 "ci_low": None, "ci_high": None, "p_adjusted": None, "reject": None,
                 "cohen_d": _cohen_d(scores[a], scores[b])}
        if result is not None:
            i, j = groups[a], groups[b]
            k, sign = (pair_index[i, j], -1.0) if i < j else (pair_index[j, i], 1.0)
            low, high = sorted(sign * float(v) for v in result.confint[k])  # statsmodels: mean_j - mean_i
            entry.update(ci_low=low, ci_high=high, p_adjusted=float(result.pvalues[k]),
                         reject=bool(result.reject[k]))
        tests.append(entry)
    return tests


def analyze_ratings(ratings: Sequence[Rating], conditions: Sequence[str] | None = None) -> dict:
    """Means, one-way and repeated-measures ANOVA and Tukey's pairwise tests of opinion scores.

    Returns
    -------
    dict
        ``{"design": "mos", "ratings", "subjects", "conditions": {name: {"n", "mean", "sd", "ci_low",
        "ci_high"}}, "by_stimulus": {stimulus: {name: mean}}, "anova": {"F", "df_between", "df_within", "p",
        "eta_squared", "omega_squared"}, "anova_rm": {"subjects", "subjects_left_out", "F", "df_condition",
        "df_error", "p", "partial_eta_squared"} (or {"skipped": why}), "tukey": [{"a", "b", "mean_difference",
        "ci_low", "ci_high", "p_adjusted", "reject", "cohen_d"}] (none past :data:`MAX_TUKEY_CONDITIONS`)}``;
        F and p are None where they are undefined, and a "note" says why: no score differs from another (no
        variance, no effect), or none differs within a condition.
    """
    require_extra(("statsmodels", "pandas"), "stats", "analysing opinion scores")
    import pandas as pd

    frame = pd.DataFrame([(r.stimulus, r.subject, r.condition, r.score) for r in ratings],
                         columns=["stimulus", "subject", "condition", "score"])
    order = _condition_order(frame["condition"].tolist(), conditions)
    per_condition = {name: _mean_interval(frame.loc[frame["condition"] == name, "score"].to_numpy(float))
                     for name in order}
    by_stimulus = {stimulus: {name: float(mine.loc[mine["condition"] == name, "score"].mean())
                              for name in order if (mine["condition"] == name).any()}
                   for stimulus, mine in frame.groupby("stimulus", sort=False)}
    return {"design": "mos", "ratings": len(frame), "subjects": int(frame["subject"].nunique()),
            "conditions": per_condition, "by_stimulus": by_stimulus, "anova": _one_way(frame),
            "anova_rm": _repeated(frame, order), "tukey": _tukey(frame, order)}


# ---------------------------------------------------------------------------------------------------------------
# identification


def analyze_identifications(answers: Sequence[Identification], classes: Sequence[str] | None = None) -> dict:
    """Accuracy per class against chance, overall accuracy, and the confusion matrix.

    Returns
    -------
    dict
        ``{"design": "identification", "answers", "subjects", "classes": [name], "chance", "overall": {"n",
        "correct", "accuracy", "ci_low", "ci_high", "p"}, "per_class": {name: {... , "p_holm"}}, "confusion":
        [[count]] (rows shown, columns answered, in the order of "classes")}``; p is the one-sided binomial
        test of accuracy above chance.
    """
    from scipy import stats

    names = list(classes) if classes is not None else sorted({a.shown for a in answers} | {a.answer for a in answers})
    index = {name: i for i, name in enumerate(names)}
    chance = 1.0 / len(names)
    confusion = np.zeros((len(names), len(names)), dtype=int)
    for answer in answers:
        confusion[index[answer.shown], index[answer.answer]] += 1

    def binomial(correct: int, n: int) -> dict:
        test = stats.binomtest(correct, n, chance, alternative="greater")
        interval = stats.binomtest(correct, n).proportion_ci(0.95, method="exact")
        return {"n": n, "correct": correct, "accuracy": correct / n, "ci_low": float(interval.low),
                "ci_high": float(interval.high), "p": float(test.pvalue)}

    per_class = {name: binomial(int(confusion[i, i]), int(confusion[i].sum()))
                 for i, name in enumerate(names) if confusion[i].sum() > 0}
    for entry, corrected in zip(per_class.values(), holm([e["p"] for e in per_class.values()]), strict=True):
        entry["p_holm"] = float(corrected)
    return {"design": "identification", "answers": len(answers), "subjects": len({a.subject for a in answers}),
            "classes": names, "chance": chance, "overall": binomial(int(np.trace(confusion)), int(confusion.sum())),
            "per_class": per_class, "confusion": confusion.tolist()}


# ---------------------------------------------------------------------------------------------------------------
# reports and figures


def _number(value: float | None, digits: int = 2) -> str:
    return "–" if value is None else f"{value:.{digits}f}"


def _p(value: float | None) -> str:
    """A p-value as reports print it: four decimals, or "< 0.0001"."""
    if value is None:
        return "–"
    return "< 0.0001" if value < 1e-4 else f"{value:.4f}"


def _p_is(value: float | None) -> str:
    """``p = 0.0123`` or ``p < 0.0001``."""
    text = _p(value)
    return f"p {text}" if text.startswith("<") else f"p = {text}"


def ratings_markdown(results: dict, *, figure: str | None = None) -> str:
    """A readable report of :func:`analyze_ratings`."""
    lines = ["# Opinion-score study", "",
             f"{results['ratings']} ratings (1 bad – 5 excellent), {results['subjects']} subject(s), "
             f"{len(results['by_stimulus'])} stimulus/stimuli.", "",
             "| condition | n | mean | sd | 95% CI |", "|---|---|---|---|---|"]
    for name, entry in results["conditions"].items():
        interval = "–" if entry["ci_low"] is None else f"[{entry['ci_low']:.2f}, {entry['ci_high']:.2f}]"
        lines.append(f"| {name} | {entry['n']} | {entry['mean']:.2f} | {entry['sd']:.2f} | {interval} |")
    if figure:
        lines += ["", f"![Mean score per condition with 95% intervals]({figure})"]
    anova = results["anova"]
    lines += ["", "## One-way ANOVA (every rating)", ""]
    if "skipped" in anova:
        lines.append(f"Not run: {anova['skipped']}.")
    else:
        lines.append(f"F({anova['df_between']}, {anova['df_within']}) = {_number(anova['F'])}, "
                     f"{_p_is(anova['p'])}, η² = {_number(anova['eta_squared'], 3)}, "
                     f"ω² = {_number(anova['omega_squared'], 3)}" + (f" ({anova['note']})" if "note" in anova else ""))
    rm = results["anova_rm"]
    lines += ["", "## Repeated-measures ANOVA (each subject's mean per condition)", ""]
    if "skipped" in rm:
        lines.append(f"Not run: {rm['skipped']}.")
    else:
        left_out = f" ({rm['subjects_left_out']} subject(s) who missed a condition left out)" \
            if rm["subjects_left_out"] else ""
        lines.append(f"{rm['subjects']} subjects{left_out}: F({rm['df_condition']}, {rm['df_error']}) = "
                     f"{_number(rm['F'])}, {_p_is(rm['p'])}, partial η² = "
                     f"{_number(rm['partial_eta_squared'], 3)}" + (f" ({rm['note']})" if "note" in rm else ""))
    if len(results["conditions"]) > MAX_TUKEY_CONDITIONS:
        lines += ["", "## Tukey's pairwise tests", "", f"Not run: {len(results['conditions'])} conditions, more than "
                  f"the {MAX_TUKEY_CONDITIONS} whose every pair is compared."]
    elif results["tukey"]:
        lines += ["", "## Tukey's pairwise tests", "", "| a − b | difference | 95% CI | p (adjusted) | Cohen's d |",
                  "|---|---|---|---|---|"]
        for test in results["tukey"]:
            interval = "–" if test["ci_low"] is None else f"[{test['ci_low']:.2f}, {test['ci_high']:.2f}]"
            lines.append(f"| {test['a']} − {test['b']} | {test['mean_difference']:.2f} | {interval} | "
                         f"{_p(test['p_adjusted'])} | {_number(test['cohen_d'])} |")
    lines += ["", "## Mean per stimulus", "", "| stimulus | " + " | ".join(results["conditions"]) + " |",
              "|---" * (len(results["conditions"]) + 1) + "|"]
    for stimulus, means in results["by_stimulus"].items():
        lines.append(f"| {stimulus} | " + " | ".join(_number(means.get(name)) for name in results["conditions"])
                     + " |")
    return "\n".join(lines) + "\n"


def identification_markdown(results: dict, *, figure: str | None = None) -> str:
    """A readable report of :func:`analyze_identifications`."""
    overall = results["overall"]
    lines = ["# Identification study", "",
             f"{results['answers']} answers, {results['subjects']} subject(s), {len(results['classes'])} classes "
             f"(chance {results['chance']:.1%}).", "",
             f"Overall: {overall['correct']} of {overall['n']} correct ({overall['accuracy']:.1%}, 95% CI "
             f"[{overall['ci_low']:.1%}, {overall['ci_high']:.1%}]), binomial p = {overall['p']:.2g} against "
             "chance.", "", "| shown | n | correct | accuracy | 95% CI | p | p (Holm) |",
             "|---|---|---|---|---|---|---|"]
    for name, entry in results["per_class"].items():
        lines.append(f"| {name} | {entry['n']} | {entry['correct']} | {entry['accuracy']:.1%} | "
                     f"[{entry['ci_low']:.1%}, {entry['ci_high']:.1%}] | {entry['p']:.2g} | {entry['p_holm']:.2g} |")
    shown, kept = confusion_shown(results)
    counts = np.asarray(results["confusion"], int)[np.ix_(kept, kept)]
    part = "" if len(kept) == len(results["classes"]) else \
        f" of the {len(kept)} classes shown most often (of {len(results['classes'])}; the JSON has them all)"
    lines += ["", f"Confusion matrix{part} (rows: shown; columns: answered):", "",
              "| shown \\ answered | " + " | ".join(shown) + " |", "|---" * (len(shown) + 1) + "|"]
    for name, row in zip(shown, counts, strict=True):
        lines.append(f"| {name} | " + " | ".join(str(v) for v in row) + " |")
    if figure:
        lines += ["", f"![Confusion matrix]({figure})"]
    return "\n".join(lines) + "\n"


def plot_means(results: dict, path: str | os.PathLike[str]) -> Path:
    """Mean score per condition with its 95% interval, as a PNG."""
    from ..evaluation.plots import new_figure, save_figure

    names = list(results["conditions"])
    entries = [results["conditions"][name] for name in names]
    figure = new_figure(figsize=(max(4.0, 1.1 * len(names) + 1.5), 3.6), layout="tight")
    axes = figure.subplots()
    means = [entry["mean"] for entry in entries]
    errors = [[0 if e["ci_low"] is None else e["mean"] - e["ci_low"] for e in entries],
              [0 if e["ci_high"] is None else e["ci_high"] - e["mean"] for e in entries]]
    axes.bar(range(len(names)), means, yerr=errors, capsize=4, color="#6a8fc7")
    axes.set_xticks(range(len(names)), names, rotation=20, ha="right")
    axes.set_ylim(1, 5)
    axes.set_ylabel("mean score (1–5)")
    axes.set_title("Opinion scores, 95% intervals")
    save_figure(figure, path, tight=True)
    return Path(path)


#: Most classes a confusion figure or table shows: past it, those shown most often (the figure's size and the
#: time to draw it grow with the square of the classes: 200 classes took 12.9 GB).
MAX_CONFUSION_CLASSES = 20


def confusion_shown(results: dict) -> tuple[list[str], list[int]]:
    """(names, indices) of the classes a confusion figure or table shows: all of them, or the
    :data:`MAX_CONFUSION_CLASSES` shown most often (ties by their order), in their order."""
    names = results["classes"]
    if len(names) <= MAX_CONFUSION_CLASSES:
        return list(names), list(range(len(names)))
    shown = np.asarray(results["confusion"], int).sum(axis=1)
    kept = sorted(np.argsort(-shown, kind="stable")[:MAX_CONFUSION_CLASSES].tolist())
    return [names[i] for i in kept], kept


def plot_confusion(results: dict, path: str | os.PathLike[str]) -> Path:
    """The confusion matrix as a PNG: each row's share of answers as colour, the counts written in; past
    :data:`MAX_CONFUSION_CLASSES` classes, the rows and columns of those shown most often (a row's share is
    still of all its answers)."""
    from ..evaluation.plots import new_figure, save_figure

    names, kept = confusion_shown(results)
    every = np.asarray(results["confusion"], float)
    counts = every[np.ix_(kept, kept)]
    shares = counts / np.maximum(every[kept].sum(axis=1, keepdims=True), 1)
    size = max(3.6, 0.8 * len(names) + 2.0)
    figure = new_figure(figsize=(size + 0.8, size), layout="tight")
    axes = figure.subplots()
    image = axes.imshow(shares, vmin=0, vmax=1, cmap="Blues")
    for i, j in itertools.product(range(len(names)), repeat=2):
        axes.text(j, i, f"{int(counts[i, j])}", ha="center", va="center",
                  color="white" if shares[i, j] > 0.6 else "black")
    axes.set_xticks(range(len(names)), names, rotation=30, ha="right")
    axes.set_yticks(range(len(names)), names)
    axes.set_xlabel("answered")
    axes.set_ylabel("shown")
    part = "" if len(kept) == len(results["classes"]) else \
        f", the {len(kept)} classes shown most often of {len(results['classes'])}"
    axes.set_title(f"Identification (chance {results['chance']:.0%}{part})")
    figure.colorbar(image, ax=axes, fraction=0.046, label="share of the row")
    save_figure(figure, path, tight=True)
    return Path(path)
