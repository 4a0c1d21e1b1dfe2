"""Paired-comparison perceptual studies (docs/studies.md): plan the presentation order, analyse the ballots.

A plan holds, per stimulus, all 16 ordered pairs of the four conditions (same-model pairs included), so each
condition is shown 4 times on the left and 4 times on the right of every stimulus. The sequence is built in
16 rounds, each showing one pair of every stimulus in shuffled order, so a stimulus's pairs are spread evenly
over the session.

A ballot gives one point to the chosen condition. A condition's score for a stimulus is its points summed
over all pairs and subjects; per-subject scores give a paired t-test for every pair of conditions.
"""

from __future__ import annotations

import csv
import io
import itertools
import math
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from audio_features.atomic import atomic_write
from audio_features.inputs import open_input, reading

from ..errors import BallotError, ConfigError
from ..motion.conditions import CONDITION_ORDER

CONDITIONS = tuple(c.value for c in CONDITION_ORDER)
PLAN_COLUMNS = ("order", "stimulus", "left", "right")
BALLOT_COLUMNS = ("stimulus", "subject", "left", "right", "choice")
#: Largest ballot file read (256 MiB: millions of ballots).
MAX_BALLOT_BYTES = 256 << 20
#: Ballot problems listed in one error message before "and N more".
_MAX_LISTED = 20
T = TypeVar("T")
_CONDITION_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_.-]{0,63}")
_STIMULUS_NAME = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9_.-]{0,127}")
#: Names a stimulus may not have: a stimulus folder holds a folder per stimulus beside these files.
_RESERVED_STIMULI = frozenset({"stimuli.json"})


def condition_name(text: str) -> str:
    """A condition's name as plans and ballots hold it: the command line's short names (none, random, speech,
    truth) become the full ones; other names (a study's own conditions) are kept if they are 1-64 letters,
    digits, ``_``, ``-`` or ``.``, starting with a letter.

    Examples
    --------
    >>> condition_name("speech"), condition_name("calm-0.5")
    ('SPEECH_DRIVEN', 'calm-0.5')
    """
    name = text.strip()
    name = SHORT_NAMES.get(name.lower(), name)
    if not _CONDITION_NAME.fullmatch(name):
        raise ConfigError(f"condition name {text!r} must be 1-64 letters, digits, '_', '-' or '.', starting with a "
                          "letter")
    return name


def condition_names(names: Sequence[str]) -> tuple[str, ...]:
    """:func:`condition_name` of each, checked to be at least two and all different."""
    chosen = tuple(condition_name(name) for name in names)
    if len(chosen) < 2:
        raise ConfigError(f"a study compares two or more conditions, got {list(names)!r}")
    if len(set(chosen)) != len(chosen):
        raise ConfigError(f"condition names repeat: {list(chosen)!r}")
    return chosen


def stimulus_names(stimuli: Sequence[str]) -> list[str]:
    """Stimulus names stripped, checked to be non-empty, different and usable as file names."""
    names = [name.strip() for name in stimuli]
    if not names or any(not name for name in names):
        raise ConfigError(f"give one or more non-empty stimulus names, got {list(stimuli)!r}")
    if len(set(names)) != len(names):
        raise ConfigError(f"stimulus names repeat: {names!r}")
    bad = [name for name in names if not _STIMULUS_NAME.fullmatch(name)]
    if bad:
        raise ConfigError(f"stimulus name(s) {', '.join(map(repr, bad))} must be 1-128 letters, digits, '_', '-' or "
                          "'.', not starting with '.' (they name files: <stimulus>.wav)")
    reserved = [name for name in names if name.lower() in _RESERVED_STIMULI]
    if reserved:
        raise ConfigError(f"stimulus name(s) {', '.join(map(repr, reserved))} name the stimulus folder's own files "
                          f"({', '.join(sorted(_RESERVED_STIMULI))}): rename the recording")
    return names


def plan_study(stimuli: Sequence[str], *, seed: int = 0,
               conditions: Sequence[str] = CONDITIONS) -> list[dict[str, str | int]]:
    """The presentation order: rows ``{"order", "stimulus", "left", "right"}``, ``order`` from 1.

    Every ordered pair of ``conditions`` (the thesis's four by default) for every stimulus, in rounds.

    Examples
    --------
    >>> rows = plan_study(["s1", "s2"], seed=1)
    >>> len(rows), sorted({row["stimulus"] for row in rows})
    (32, ['s1', 's2'])
    """
    names = stimulus_names(stimuli)
    generator = np.random.default_rng(seed)
    chosen = condition_names(conditions)
    pairs = list(itertools.product(chosen, chosen))
    per_stimulus = {name: [pairs[i] for i in generator.permutation(len(pairs))] for name in names}
    return [{"order": k + 1, "stimulus": s, "left": left, "right": right}
            for k, (s, (left, right)) in enumerate(in_rounds(per_stimulus, generator))]


def in_rounds(per_stimulus: dict[str, list[T]], generator: np.random.Generator) -> list[tuple[str, T]]:
    """``(stimulus, entry)`` in rounds: round r shows the r-th entry of every stimulus that has one, the stimuli
    in shuffled order, never the same stimulus twice in a row across rounds (where another can go first)."""
    sequence: list[tuple[str, T]] = []
    for round_index in range(max(map(len, per_stimulus.values()), default=0)):
        names = [name for name, entries in per_stimulus.items() if round_index < len(entries)]
        order = [names[i] for i in generator.permutation(len(names))]
        if sequence and len(order) > 1 and order[0] == sequence[-1][0]:
            order[0], order[-1] = order[-1], order[0]
        sequence += [(name, per_stimulus[name][round_index]) for name in order]
    return sequence


def write_plan(rows: Sequence[dict], path: str | os.PathLike[str]) -> None:
    """Write a plan as CSV (atomically): the columns ``order,stimulus,left,right`` of a paired plan, or
    those of the rows (``order,stimulus,condition`` or ``order,stimulus,shown``)."""
    if not rows:
        raise ConfigError("the plan has no rows")
    with atomic_write(path) as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)


@dataclass(frozen=True)
class Ballot:
    row: int  # line number in the file (the header is line 1)
    stimulus: str
    subject: str
    left: str
    right: str
    choice: str

    @property
    def chosen(self) -> str:
        return self.left if self.choice == "left" else self.right


def ballot_error(source: str, problems: list[str]) -> BallotError:
    listed = problems[:_MAX_LISTED]
    more = f"; and {len(problems) - _MAX_LISTED} more" if len(problems) > _MAX_LISTED else ""
    return BallotError(f"{source}: {len(problems)} bad ballot row(s): " + "; ".join(listed) + more)


#: The short condition names of the command line, read in ballots as their full names.
SHORT_NAMES = {"none": "NO_PROSODY", "random": "RANDOM", "speech": "SPEECH_DRIVEN", "truth": "GROUND_TRUTH"}


def _rows(reader, source: str):
    """``(line, cells)`` of a CSV reader; a malformed row (a cell over the csv module's size limit, a stray
    quote) is a BallotError naming its line."""
    while True:
        try:
            cells = next(reader)
        except StopIteration:
            return
        except csv.Error as error:
            raise BallotError(f"{source}, line {reader.line_num}: not a CSV row ({error})") from None
        yield reader.line_num, cells


def header_index(reader, source: str, columns: Sequence[str], optional: Sequence[str] = ()) -> dict[str, int]:
    """The position of each of ``columns`` (and of those of ``optional`` present) in a ballot file's header,
    read from ``reader``; a BallotError when the file is empty or lacks a column."""
    header = next(_rows(reader, source), (1, None))[1]
    if header is None:
        raise BallotError(f"{source}: the file is empty; expected the header {','.join(columns)}")
    names = [cell.strip().lower() for cell in header]
    missing = [name for name in columns if name not in names]
    if missing:
        raise BallotError(f"{source}, line 1: the header lacks {', '.join(missing)}; expected columns "
                          f"{','.join(columns)}")
    return {name: names.index(name) for name in (*columns, *optional) if name in names}


def filled_rows(text: str, source: str, columns: Sequence[str],
                optional: Sequence[str] = ()) -> tuple[list[tuple[int, dict[str, str]]], list[str]]:
    """``(line, {column: value})`` of each non-empty row of a ballot file's text with every column filled, and
    one problem line for each row that is not."""
    reader = csv.reader(io.StringIO(text))
    index = header_index(reader, source, columns, optional)
    records, problems = [], []
    for line, cells in _rows(reader, source):
        if not any(cell.strip() for cell in cells):
            continue
        values = {name: cells[i].strip() if i < len(cells) else "" for name, i in index.items()}
        empty = [name for name, value in values.items() if not value]
        if empty:
            problems.append(f"row {line} is incomplete (no {', '.join(empty)})")
            continue
        records.append((line, values))
    return records, problems


def parse_ballots(text: str, *, source: str = "<ballots>", conditions: Sequence[str] = CONDITIONS) -> list[Ballot]:
    """Parse ballot CSV text (columns ``stimulus,subject,left,right,choice``; extra columns are ignored).

    ``conditions``: the names a ballot may give (the thesis's four by default; a plan's own).

    Raises
    ------
    BallotError
        Missing columns, or rows that are incomplete, duplicated (same stimulus, subject and ordered pair),
        name an unknown condition, or choose neither ``left`` nor ``right``; every bad row is listed by its
        line number.
    """
    records, problems = filled_rows(text, source, BALLOT_COLUMNS)
    ballots: list[Ballot] = []
    seen: dict[tuple[str, str, str, str], int] = {}
    for line, values in records:
        for side in ("left", "right"):  # the short names the other commands take are read too
            values[side] = SHORT_NAMES.get(values[side].lower(), values[side])
        unknown = [values[side] for side in ("left", "right") if values[side] not in conditions]
        if unknown:
            problems.append(f"row {line} names unknown condition(s) {', '.join(map(repr, unknown))} "
                            f"(expected {', '.join(conditions)})")
            continue
        choice = values["choice"].lower()
        if choice not in ("left", "right"):
            problems.append(f"row {line} has choice {values['choice']!r} (expected left or right)")
            continue
        key = (values["stimulus"], values["subject"], values["left"], values["right"])
        if key in seen:
            problems.append(f"row {line} duplicates row {seen[key]} ({key[0]}, subject {key[1]}, "
                            f"{key[2]} vs {key[3]})")
            continue
        seen[key] = line
        ballots.append(Ballot(line, values["stimulus"], values["subject"], values["left"], values["right"], choice))
    if problems:
        raise ballot_error(source, problems)
    if not ballots:
        raise BallotError(f"{source}: no ballot rows")
    return ballots


def read_text_file(path: str | os.PathLike[str], *, what: str = "CSV") -> str:
    """The text of a ballot or plan file (UTF-8, a byte-order mark allowed, at most
    :data:`MAX_BALLOT_BYTES`); a BallotError naming the file when it cannot be read."""
    try:
        with reading(path, BallotError), open_input(path, text=True, encoding="utf-8-sig", newline="",
                                                    max_bytes=MAX_BALLOT_BYTES) as handle:
            return handle.read()
    except UnicodeDecodeError as error:
        raise BallotError(f"{path}: cannot be read as {what} text ({error})") from None


def read_ballots(path: str | os.PathLike[str], *, conditions: Sequence[str] = CONDITIONS) -> list[Ballot]:
    """Read and check a ballot file (see :func:`parse_ballots`)."""
    return parse_ballots(read_text_file(path), source=str(path), conditions=conditions)


def missing_pairs(ballots: Sequence[Ballot], conditions: Sequence[str] = CONDITIONS) -> list[str]:
    """Subjects who did not judge every ordered pair of a stimulus (16 of the four conditions), one line each."""
    judged: dict[tuple[str, str], set[tuple[str, str]]] = {}
    for ballot in ballots:
        judged.setdefault((ballot.stimulus, ballot.subject), set()).add((ballot.left, ballot.right))
    notes = []
    for (stimulus, subject), pairs in judged.items():
        if len(pairs) < len(conditions) ** 2:
            notes.append(f"subject {subject} judged {len(pairs)} of {len(conditions) ** 2} pairs of {stimulus}")
    return notes


def _t_quantile_975(df: int) -> float:
    from scipy import stats

    return float(stats.t.ppf(0.975, df))


def paired_t_test(a: np.ndarray, b: np.ndarray) -> dict[str, float | int | None]:
    """Paired t-test of ``a - b`` (``scipy.stats.ttest_rel``): mean, sd (n - 1), se, 95% CI, t, df = n - 1,
    two-tailed p.

    ``t`` and ``p`` (and the CI) are None where undefined: fewer than two subjects, or no spread in the
    differences.
    """
    return paired_t_tests(np.asarray(a, float)[:, None], np.asarray(b, float)[:, None])[0]


def analyze_ballots(ballots: Sequence[Ballot], conditions: Sequence[str] = CONDITIONS) -> dict:
    """Scores per stimulus and condition, and the paired t-tests between conditions per stimulus.

    Returns
    -------
    dict
        ``{"scores": {stimulus: {condition: int}}, "ttests": [{"stimulus", "a", "b", "mean", "sd", "se",
        "ci_low", "ci_high", "t", "df", "p", "p_holm"}]}`` (``p_holm``: Holm-corrected over the stimulus's
        tests); a comes before b in the order of ``conditions`` (NO_PROSODY, RANDOM, SPEECH_DRIVEN,
        GROUND_TRUTH by default) and the differences are a minus b over the subjects who judged the stimulus.
    """
    by_stimulus: dict[str, list[Ballot]] = {}
    for ballot in ballots:  # one pass: the work grows with the ballots, not with ballots x stimuli
        by_stimulus.setdefault(ballot.stimulus, []).append(ballot)
    column = {name: i for i, name in enumerate(conditions)}
    pairs = list(itertools.combinations(range(len(conditions)), 2))
    scores: dict[str, dict[str, int]] = {}
    tests: list[dict] = []
    # the tests of all stimuli judged by the same number of subjects run as one vectorised call
    groups: dict[int, list[tuple[int, np.ndarray, np.ndarray]]] = {}
    for stimulus, mine in by_stimulus.items():
        subjects = {subject: i for i, subject in enumerate(dict.fromkeys(ballot.subject for ballot in mine))}
        per_subject = np.zeros((len(subjects), len(conditions)), dtype=int)
        for ballot in mine:
            per_subject[subjects[ballot.subject], column[ballot.chosen]] += 1
        scores[stimulus] = {name: int(per_subject[:, i].sum()) for i, name in enumerate(conditions)}
        for i, j in pairs:
            groups.setdefault(len(subjects), []).append((len(tests), per_subject[:, i], per_subject[:, j]))
            tests.append({"stimulus": stimulus, "a": conditions[i], "b": conditions[j]})
    for members in groups.values():
        indices = [index for index, _, _ in members]
        results = paired_t_tests(np.column_stack([a for _, a, _ in members]),
                                 np.column_stack([b for _, _, b in members]))
        for index, result in zip(indices, results, strict=True):
            tests[index].update(result)
    _add_holm(tests)
    return {"scores": scores, "ttests": tests}


def paired_t_tests(a: np.ndarray, b: np.ndarray) -> list[dict[str, float | int | None]]:
    """:func:`paired_t_test` of each column of ``a`` (n, k) against the same column of ``b``, in one
    ``scipy.stats.ttest_rel`` call."""
    from scipy import stats

    a = np.asarray(a, float).reshape(a.shape[0], -1)
    b = np.asarray(b, float).reshape(b.shape[0], -1)
    n = a.shape[0]
    difference = a - b
    mean = difference.mean(axis=0)
    sd = difference.std(axis=0, ddof=1) if n > 1 else np.zeros(difference.shape[1])
    se = sd / math.sqrt(n) if n > 1 else np.zeros(difference.shape[1])
    defined = se > 0
    t = np.full(mean.shape, np.nan)
    p = np.full(mean.shape, np.nan)
    if n > 1 and defined.any():
        test = stats.ttest_rel(a[:, defined], b[:, defined], axis=0)  # two-tailed, df = n - 1
        t[defined], p[defined] = test.statistic, test.pvalue
    half = _t_quantile_975(n - 1) * se if n > 1 else np.zeros_like(se)
    results: list[dict[str, float | int | None]] = []
    for k in range(mean.size):
        ok = bool(defined[k])
        results.append({"mean": float(mean[k]), "sd": float(sd[k]), "se": float(se[k]),
                        "ci_low": float(mean[k] - half[k]) if ok else None,
                        "ci_high": float(mean[k] + half[k]) if ok else None,
                        "t": float(t[k]) if ok else None, "df": n - 1, "p": float(p[k]) if ok else None})
    return results


def holm(p_values: Sequence[float]) -> np.ndarray:
    """Holm's step-down correction of one family of p-values: the k-th smallest times (m - k + 1), made
    non-decreasing, capped at 1 (the same as ``statsmodels.stats.multitest.multipletests(p, method="holm")``,
    which the tests check, without its garbage collection on every call: 27 ms a family).

    Examples
    --------
    >>> holm([0.04, 0.01, 0.03]).round(6).tolist()
    [0.06, 0.03, 0.06]
    """
    values = np.asarray(p_values, float)
    order = np.argsort(values, kind="stable")
    scaled = values[order] * np.arange(values.size, 0, -1)
    corrected = np.empty_like(values)
    corrected[order] = np.minimum(np.maximum.accumulate(scaled), 1.0)
    return corrected


def _add_holm(tests: list[dict]) -> None:
    """``p_holm``: each stimulus's six p-values corrected together by Holm's step-down method, so that a
    study reads its pairwise comparisons at a family-wise 5 %; None where p is."""
    by_stimulus: dict[str, list[dict]] = {}
    for test in tests:
        test["p_holm"] = None
        if test["p"] is not None:
            by_stimulus.setdefault(test["stimulus"], []).append(test)
    for family in by_stimulus.values():
        for test, value in zip(family, holm([test["p"] for test in family]), strict=True):
            test["p_holm"] = float(value)


def confusion_matrix(ballots: Sequence[Ballot], stimulus: str, conditions: Sequence[str] = CONDITIONS) -> np.ndarray:
    """``m[i, j]``: how often condition i was chosen when shown with condition j (either side)."""
    matrix = np.zeros((len(conditions), len(conditions)), dtype=int)
    for ballot in ballots:
        if ballot.stimulus != stimulus:
            continue
        other = ballot.right if ballot.choice == "left" else ballot.left
        matrix[conditions.index(ballot.chosen), conditions.index(other)] += 1
    return matrix


def study_markdown(ballots: Sequence[Ballot], results: dict, *, notes: Sequence[str] = (),
                   conditions: Sequence[str] = CONDITIONS) -> str:
    """A readable report: per stimulus the confusion matrix, the scores and the t-tests."""

    def number(value: float | None, digits: int = 2) -> str:
        return "–" if value is None else f"{value:.{digits}f}"

    lines = ["# Paired-comparison study", "",
             f"{len(ballots)} ballots, {len({b.subject for b in ballots})} subject(s), "
             f"{len(results['scores'])} stimulus/stimuli."]
    if notes:
        lines += ["", "Notes:", *(f"- {note}" for note in notes)]
    by_stimulus: dict[str, list[Ballot]] = {}
    for ballot in ballots:
        by_stimulus.setdefault(ballot.stimulus, []).append(ballot)
    tests_by_stimulus: dict[str, list[dict]] = {}
    for test in results["ttests"]:
        tests_by_stimulus.setdefault(test["stimulus"], []).append(test)
    for stimulus, scores in results["scores"].items():
        lines += ["", f"## {stimulus}", "", "Times the row condition was chosen when shown with the column "
                  "condition (either side):", "", "| chosen \\ against | " + " | ".join(conditions) + " |",
                  "|---" * (len(conditions) + 1) + "|"]
        matrix = confusion_matrix(by_stimulus.get(stimulus, []), stimulus, conditions)
        for i, name in enumerate(conditions):
            lines.append(f"| {name} | " + " | ".join(str(v) for v in matrix[i]) + " |")
        lines += ["", "| condition | score |", "|---|---|"]
        lines += [f"| {name} | {scores[name]} |" for name in conditions]
        lines += ["", "| a − b | mean | sd | se | 95% CI | t | df | p | p (Holm) |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for test in tests_by_stimulus.get(stimulus, []):
            ci = ("–" if test["ci_low"] is None else f"[{test['ci_low']:.2f}, {test['ci_high']:.2f}]")
            lines.append(f"| {test['a']} − {test['b']} | {number(test['mean'])} | {number(test['sd'])} | "
                         f"{number(test['se'])} | {ci} | {number(test['t'])} | {test['df']} | "
                         f"{number(test['p'], 4)} | {number(test.get('p_holm'), 4)} |")
    return "\n".join(lines) + "\n"
