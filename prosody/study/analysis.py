"""A study's ballots analysed by their design, from Python as ``prosody study analyze`` does it.

The design is read from the ballots' columns (:func:`prosody.study.ratings.ballot_design`): paired comparisons
(Zavala Chmelicka 2005), opinion scores (Jia et al. 2013) or identification (Wu et al. 2006). With the plan, the
ballots must be of its design and name only its stimuli, and its conditions order the results.

Examples
--------
>>> import pathlib, tempfile
>>> folder = pathlib.Path(tempfile.mkdtemp())
>>> _ = (folder / "ballots.csv").write_text("stimulus,subject,shown,answer\\n"
...     "a,s1,happy,happy\\na,s1,sad,sad\\nb,s2,happy,sad\\nb,s2,sad,sad\\n")
>>> analysis = analyze_study(folder / "ballots.csv")
>>> analysis.design, analysis.results["overall"]["correct"]
('identification', 3)
>>> write_analysis(analysis, folder / "results.json")
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import BallotError
from . import ratings
from .ballots import CONDITIONS, analyze_ballots, missing_pairs, parse_ballots, read_text_file, study_markdown
from .designs import StudyPlan, read_plan

__all__ = ["StudyAnalysis", "analyze_study", "write_analysis"]


@dataclass(frozen=True)
class StudyAnalysis:
    """The analysis of one ballot file: its design, the answers read, the results (JSON-ready), a one-line
    summary and the notes about what the ballots lack (paired designs: pairs nobody compared)."""

    design: str
    answers: Sequence[Any]
    results: dict
    summary: str
    conditions: Sequence[str] | None = None
    notes: tuple[str, ...] = ()

    def report(self, figure: str | None = None) -> str:
        """The report in Markdown; ``figure`` is the file name of the figure it shows (opinion scores and
        identification)."""
        if self.design == "paired":
            return study_markdown(self.answers, self.results, notes=self.notes,
                                  conditions=self.conditions or CONDITIONS)
        if self.design == "mos":
            return ratings.ratings_markdown(self.results, figure=figure)
        return ratings.identification_markdown(self.results, figure=figure)

    @property
    def draw(self) -> Callable[[dict, str | os.PathLike[str]], Path] | None:
        """The function that draws the report's figure from the results, or None (paired designs)."""
        return {"mos": ratings.plot_means, "identification": ratings.plot_confusion}.get(self.design)

    def figure_path(self, report: str | os.PathLike[str]) -> Path:
        """Where the figure of the report ``report`` goes: beside it, named after it."""
        report = Path(report)
        return report.with_name(report.stem + (".confusion.png" if self.design == "identification" else ".means.png"))


def analyze_study(ballots: str | os.PathLike[str], plan: StudyPlan | str | os.PathLike[str] | None = None,
                  ) -> StudyAnalysis:
    """Read and analyse a ballot file by its design.

    Parameters
    ----------
    ballots : path-like
        The ballot file (CSV; as ``prosody study export`` writes or by hand).
    plan : StudyPlan or path-like, optional
        The study's plan: the ballots must be of its design and name only its stimuli; its conditions order the
        results.

    Returns
    -------
    StudyAnalysis

    Raises
    ------
    BallotError
        The ballots are malformed, of another design than the plan's, or name a stimulus the plan does not.
    """
    source = str(ballots)
    plan_name = None
    if plan is not None and not isinstance(plan, StudyPlan):
        plan_name, plan = str(plan), read_plan(plan)
    text = read_text_file(ballots)
    design = ratings.ballot_design(text)
    if plan is not None and plan.design != design:
        raise BallotError(f"{source}: {design} ballots, but {plan_name or 'the plan'} is a {plan.design} plan")
    conditions = list(plan.conditions) if plan is not None else None
    notes: list[str] = []
    if design == "paired":
        answers: list = parse_ballots(text, source=source, conditions=conditions or CONDITIONS)
        notes = missing_pairs(answers, conditions or CONDITIONS)
        results = analyze_ballots(answers, conditions or CONDITIONS)
        summary = f"{len(answers)} ballots, {len(results['scores'])} stimulus/stimuli"
    elif design == "mos":
        answers = ratings.parse_ratings(text, source=source, conditions=conditions)
        results = ratings.analyze_ratings(answers, conditions)
        summary = f"{len(answers)} ratings by {results['subjects']} subject(s)"
    else:
        answers = ratings.parse_identifications(text, source=source, classes=conditions)
        results = ratings.analyze_identifications(answers, conditions)
        summary = (f"{len(answers)} answers by {results['subjects']} subject(s), "
                   f"{results['overall']['accuracy']:.1%} correct (chance {results['chance']:.1%})")
    if plan is not None:
        strangers = [f"row {b.row} ({b.stimulus})" for b in answers if b.stimulus not in plan.stimuli]
        if strangers:
            raise BallotError(f"{source}: {len(strangers)} ballot row(s) name a stimulus that is not in "
                              f"{plan_name or 'the plan'}: " + ", ".join(strangers[:20])
                              + (", ..." if len(strangers) > 20 else ""))
    return StudyAnalysis(design, answers, results, summary, conditions, tuple(notes))


def write_analysis(analysis: StudyAnalysis, output: str | os.PathLike[str],
                   report: str | os.PathLike[str] | None = None) -> None:
    """Write the results (JSON) and, with ``report``, the Markdown report and its figure beside it: every file
    under a temporary name, renamed only once all of them are complete.

    Parameters
    ----------
    analysis : StudyAnalysis
        What :func:`analyze_study` found.
    output : path-like
        The results file (JSON).
    report : path-like, optional
        The report (Markdown); its figure is :meth:`StudyAnalysis.figure_path`.
    """
    from audio_features.atomic import atomic_path, atomic_write

    with contextlib.ExitStack() as pending:
        handle = pending.enter_context(atomic_write(output, newline="\n"))
        json.dump(analysis.results, handle, indent=1, allow_nan=False)
        handle.write("\n")
        if report is not None:
            figure = analysis.figure_path(report)
            if analysis.draw is not None:
                analysis.draw(analysis.results, pending.enter_context(atomic_path(figure)))
            pending.enter_context(atomic_write(report, newline="\n")).write(analysis.report(figure.name))
