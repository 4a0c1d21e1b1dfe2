"""The three designs of a perceptual study and their plans (``prosody study plan --design``).

- ``paired`` (the thesis): every ordered pair of the conditions per stimulus; the participant chooses the face
  that moves more naturally. Plan columns ``order,stimulus,left,right`` (:func:`prosody.study.ballots.plan_study`).
- ``mos`` (Jia et al. 2013): every condition of every stimulus once, rated from 1 (bad) to 5 (excellent). Plan columns
  ``order,stimulus,condition``.
- ``identification`` (Wu et al. 2006): every condition of every stimulus shown ``repeats`` times; the participant says
  which of the conditions (expressions, say) it is. Plan columns ``order,stimulus,shown``; the answer options are
  the plan's conditions.

A plan is the study's order for one participant. :func:`participant_trials` turns it into each participant's
own: the sequence reshuffled (by rounds, so a stimulus's trials stay spread out) and, in paired plans, the sides
swapped for every second participant, so that each ordered pair is seen both ways across participants.
"""

from __future__ import annotations

import csv
import hashlib
import io
import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import BallotError, ConfigError
from .ballots import (
    CONDITIONS,
    PLAN_COLUMNS,
    condition_name,
    condition_names,
    in_rounds,
    plan_study,
    read_text_file,
    stimulus_names,
)

DESIGNS = ("paired", "mos", "identification")
#: The column naming the condition of a trial, per design (paired trials have two: left and right).
CONDITION_COLUMNS = {"paired": ("left", "right"), "mos": ("condition",), "identification": ("shown",)}
#: Largest plan read, in trials (a thousand stimuli of the 16 thesis pairs).
MAX_PLAN_TRIALS = 100_000


@dataclass(frozen=True)
class Trial:
    """One presentation of a plan: ``conditions`` is (left, right) in paired plans, else (the condition,)."""

    order: int
    stimulus: str
    conditions: tuple[str, ...]

    def as_row(self, design: str) -> dict[str, str | int]:
        return {"order": self.order, "stimulus": self.stimulus,
                **dict(zip(CONDITION_COLUMNS[design], self.conditions, strict=True))}


@dataclass(frozen=True)
class StudyPlan:
    """A plan read from its CSV file: the design (from the columns), its trials, stimuli and conditions."""

    design: str
    trials: tuple[Trial, ...]
    stimuli: tuple[str, ...]
    conditions: tuple[str, ...]
    sha256: str

    @property
    def rows(self) -> list[dict[str, str | int]]:
        return [trial.as_row(self.design) for trial in self.trials]


def _ordered_conditions(names: Sequence[str]) -> tuple[str, ...]:
    """The thesis's four in their order, then a study's own names in alphabetical order."""
    seen = set(names)
    return tuple(name for name in CONDITIONS if name in seen) + tuple(sorted(seen - set(CONDITIONS)))


def plan_single(stimuli: Sequence[str], conditions: Sequence[str], *, design: str, seed: int = 0,
                repeats: int = 1) -> list[dict[str, str | int]]:
    """A ``mos`` or ``identification`` plan: each condition of each stimulus ``repeats`` times, in rounds
    (round r shows one condition of every stimulus), the conditions of a stimulus in shuffled order.

    Examples
    --------
    >>> rows = plan_single(["a", "b"], ["none", "speech"], design="mos", seed=1)
    >>> len(rows), sorted(rows[0])
    (4, ['condition', 'order', 'stimulus'])
    """
    if design not in ("mos", "identification"):
        raise ConfigError(f"plan_single makes mos and identification plans, not {design!r}")
    if not 1 <= repeats <= 100:
        raise ConfigError(f"repeats must be a whole number from 1 to 100, got {repeats!r}")
    names = stimulus_names(stimuli)
    chosen = condition_names(conditions)
    generator = np.random.default_rng(seed)
    shown = list(chosen) * repeats
    per_stimulus = {name: [shown[i] for i in generator.permutation(len(shown))] for name in names}
    column = CONDITION_COLUMNS[design][0]
    return [{"order": k + 1, "stimulus": stimulus, column: condition}
            for k, (stimulus, condition) in enumerate(in_rounds(per_stimulus, generator))]


def make_plan(stimuli: Sequence[str], *, design: str = "paired", conditions: Sequence[str] | None = None,
              seed: int = 0, repeats: int = 1) -> list[dict[str, str | int]]:
    """The plan rows of ``design``; ``conditions`` default to the thesis's four (identification needs its own)."""
    if design not in DESIGNS:
        raise ConfigError(f"design {design!r} is not one of {', '.join(DESIGNS)}")
    if conditions is None:
        if design == "identification":
            raise ConfigError("an identification study needs its conditions (the answers people choose from): "
                              "give --conditions NAME,NAME,...")
        conditions = CONDITIONS
    if design == "paired" and repeats != 1:
        raise ConfigError("--repeats is for mos and identification plans; a paired plan shows every ordered "
                          "pair once")
    each = len(conditions) ** 2 if design == "paired" else len(conditions) * repeats
    if len(stimuli) * each > MAX_PLAN_TRIALS:  # refused here, not later by the stimuli and the server
        raise ConfigError(f"{len(stimuli)} stimuli x {each} presentations each is {len(stimuli) * each} trials, more "
                          f"than the {MAX_PLAN_TRIALS} a plan may hold: fewer stimuli, conditions or repeats")
    if design == "paired":
        return plan_study(stimuli, seed=seed, conditions=conditions)
    return plan_single(stimuli, conditions, design=design, seed=seed, repeats=repeats)


def parse_plan(text: str, *, source: str = "<plan>") -> StudyPlan:
    """Read a plan's CSV text; its columns say the design.

    Raises
    ------
    BallotError
        Not a plan (unknown columns), orders that are not 1..n, bad names, or no trials.
    """
    reader = csv.reader(io.StringIO(text))
    try:
        header = [cell.strip().lower() for cell in next(reader)]
    except StopIteration:
        raise BallotError(f"{source}: the plan is empty") from None
    except csv.Error as error:
        raise BallotError(f"{source}, line 1: not a CSV row ({error})") from None
    design = next((name for name, columns in CONDITION_COLUMNS.items()
                   if set(header) == {"order", "stimulus", *columns}), None)
    if design is None:
        raise BallotError(f"{source}: not a study plan (columns {','.join(header)}; expected "
                          f"{','.join(PLAN_COLUMNS)}, order,stimulus,condition or order,stimulus,shown)")
    index = {name: header.index(name) for name in header}
    trials: list[Trial] = []
    try:
        for cells in reader:
            if not any(cell.strip() for cell in cells):
                continue
            line = reader.line_num
            if len(cells) != len(header):
                raise BallotError(f"{source}, line {line}: {len(cells)} cells, expected {len(header)}")
            if len(trials) >= MAX_PLAN_TRIALS:
                raise BallotError(f"{source}: more than {MAX_PLAN_TRIALS} trials")
            try:
                order = int(cells[index["order"]])
                names = tuple(condition_name(cells[index[column]]) for column in CONDITION_COLUMNS[design])
                stimulus = stimulus_names([cells[index["stimulus"]]])[0]
            except (ValueError, ConfigError) as error:
                raise BallotError(f"{source}, line {line}: {error}") from None
            trials.append(Trial(order, stimulus, names))
    except csv.Error as error:
        raise BallotError(f"{source}, line {reader.line_num}: not a CSV row ({error})") from None
    if not trials:
        raise BallotError(f"{source}: the plan has no trials")
    if [trial.order for trial in trials] != list(range(1, len(trials) + 1)):
        raise BallotError(f"{source}: the order column must count 1, 2, ... {len(trials)} down the file")
    conditions = _ordered_conditions([name for trial in trials for name in trial.conditions])
    if len(conditions) < 2:
        raise BallotError(f"{source}: a study compares two or more conditions; the plan has {conditions[0]} only")
    stimuli = tuple(dict.fromkeys(trial.stimulus for trial in trials))
    return StudyPlan(design, tuple(trials), stimuli, conditions, hashlib.sha256(text.encode()).hexdigest())


def read_plan(path: str | os.PathLike[str]) -> StudyPlan:
    """Read and check a plan file (see :func:`parse_plan`)."""
    return parse_plan(read_text_file(path, what="plan"), source=str(path))


def participant_trials(plan: StudyPlan, ordinal: int) -> list[Trial]:
    """Participant number ``ordinal`` (from 1)'s own trials: the plan's reshuffled by rounds (the first
    participant sees the plan's order), and in a paired plan the sides swapped for every second participant.
    ``order`` keeps the plan's trial number. The same ordinal always gives the same trials.

    Examples
    --------
    >>> plan = parse_plan("order,stimulus,left,right\\n1,a,NO_PROSODY,RANDOM\\n2,b,RANDOM,NO_PROSODY\\n")
    >>> [(t.order, t.conditions) for t in participant_trials(plan, 2)]  # the second participant: sides swapped
    [(1, ('RANDOM', 'NO_PROSODY')), (2, ('NO_PROSODY', 'RANDOM'))]
    """
    if ordinal < 1:
        raise ConfigError(f"participant numbers start at 1, got {ordinal!r}")
    trials = list(plan.trials)
    if ordinal > 1:
        generator = np.random.default_rng([int(plan.sha256[:15], 16), ordinal])
        per_stimulus: dict[str, list[Trial]] = {}
        for trial in trials:
            per_stimulus.setdefault(trial.stimulus, []).append(trial)
        lists = {name: [mine[i] for i in generator.permutation(len(mine))] for name, mine in per_stimulus.items()}
        trials = [trial for _, trial in in_rounds(lists, generator)]
    if plan.design == "paired" and ordinal % 2 == 0:
        trials = [Trial(trial.order, trial.stimulus, trial.conditions[::-1]) for trial in trials]
    return trials
