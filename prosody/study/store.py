"""The answers of a running study, in one SQLite database (``prosody study serve --db``, ``study export``).

Every change is one transaction in write-ahead-log mode with full synchronisation, so a crash, a killed server
or a closed tab loses no answer that was acknowledged. The database holds:

- ``meta``: this project's format name and version, the design and the plan (its text and SHA-256), so a
  database is never mixed with another plan's and can be exported without it;
- ``participants``: an anonymous random ID per participant, their number (1, 2, ... in order of arrival, which
  chooses their counterbalanced order), their completion code, when they started and finished;
- ``trials``: each participant's own sequence (:func:`prosody.study.designs.participant_trials`), fixed
  when they arrive, so that resuming shows the same trials;
- ``answers``: one row per participant and trial position (the primary key): a second submission of the same
  answer is acknowledged and counted once; a different one for a trial already answered is refused.

Answers are given in order: the next trial is the first unanswered one.
"""

from __future__ import annotations

import csv
import datetime
import io
import os
import secrets
import sqlite3
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from ..errors import ConfigError, ProsodyError
from .ballots import BALLOT_COLUMNS
from .designs import CONDITION_COLUMNS, StudyPlan, participant_trials
from .ratings import IDENTIFICATION_COLUMNS, MOS_COLUMNS, SCORES

STORE_FORMAT = "visual-prosody-study-db"
STORE_VERSION = 1
#: The ballot columns an export writes, per design (then ``order``: the plan's trial number).
EXPORT_COLUMNS = {"paired": BALLOT_COLUMNS, "mos": MOS_COLUMNS, "identification": IDENTIFICATION_COLUMNS}
_SCHEMA = """
CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE participants (id TEXT PRIMARY KEY, ordinal INTEGER NOT NULL UNIQUE, code TEXT NOT NULL,
                           started TEXT NOT NULL, finished TEXT);
CREATE TABLE trials (participant TEXT NOT NULL REFERENCES participants(id), position INTEGER NOT NULL,
                     plan_order INTEGER NOT NULL, stimulus TEXT NOT NULL, first TEXT NOT NULL, second TEXT,
                     PRIMARY KEY (participant, position));
CREATE TABLE answers (participant TEXT NOT NULL, position INTEGER NOT NULL, answer TEXT NOT NULL,
                      seconds REAL, answered TEXT NOT NULL, PRIMARY KEY (participant, position),
                      FOREIGN KEY (participant, position) REFERENCES trials(participant, position));
"""


class StudyStoreError(ProsodyError, ValueError):
    """An answer or participant the study refuses (unknown participant, a trial out of turn, a bad answer)."""

    def __init__(self, message: str, *, status: int = 400) -> None:
        super().__init__(message)
        self.status = status


def _now() -> str:
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


class StudyStore:
    """The database of one study and plan: opened (or made) at ``path``; safe to use from many threads.

    Raises
    ------
    ConfigError
        The file is not an SQLite database, is another program's, or was made for another plan.
    """

    def __init__(self, path: str | os.PathLike[str], plan: StudyPlan | None = None, *, create: bool = True) -> None:
        self.path = Path(path)
        exists = self.path.exists()
        if not exists and (not create or plan is None):
            raise ConfigError(f"{path}: no such study database")
        if exists and not self.path.is_file():
            raise ConfigError(f"{path}: not a study database (not a regular file)")
        try:
            self._db = self._connect(read_only=exists and not create)
            tables = {row[0] for row in self._db.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        except sqlite3.OperationalError as error:  # there, but not to be opened or read (permissions, media)
            raise ConfigError(f"{path}: the study database cannot be read ({error})") from None
        except sqlite3.DatabaseError as error:
            raise ConfigError(f"{path}: not a study database ({error})") from None
        self._lock = threading.RLock()
        if not tables:
            if plan is None:
                raise ConfigError(f"{path}: an empty database; 'prosody study serve' makes it")
            self._create(plan)
        elif "meta" not in tables:
            self.close()
            raise ConfigError(f"{path}: not a study database of this project (tables {', '.join(sorted(tables))})")
        try:
            meta = dict(self._db.execute("SELECT key, value FROM meta"))
        except (sqlite3.DatabaseError, ValueError) as error:
            self.close()
            raise ConfigError(f"{path}: the study database is damaged ({error})") from None
        if meta.get("format") != STORE_FORMAT or meta.get("version") != str(STORE_VERSION):
            self.close()
            raise ConfigError(f"{path}: not a study database of this project (format {meta.get('format')!r})")
        missing = [key for key in ("design", "plan_sha256", "conditions", "trials") if key not in meta]
        if missing or not str(meta.get("trials", "")).isdigit():
            self.close()
            raise ConfigError(f"{path}: the study database is damaged (its record of the study lacks "
                              f"{', '.join(missing) or 'a trial count'})")
        if plan is not None and meta.get("plan_sha256") != plan.sha256:
            self.close()
            raise ConfigError(f"{path}: this database holds a study of another plan; give that plan, or a new "
                              "--db for this one")
        self.design = meta["design"]
        self.plan_sha256 = meta["plan_sha256"]
        self.conditions = tuple(meta["conditions"].split(","))
        self.total = int(meta["trials"])
        self.plan = plan

    def _connect(self, *, read_only: bool) -> sqlite3.Connection:
        """The connection: read-only for a reader (export), so that a database on read-only media is read; a
        database in WAL mode whose folder cannot be written is read as immutable."""
        def connect(target: str | Path, *, uri: bool = False) -> sqlite3.Connection:
            return sqlite3.connect(target, timeout=10.0, isolation_level=None, check_same_thread=False, uri=uri)

        if not read_only:
            db = connect(self.path)
        else:
            address = self.path.resolve().as_uri()
            db = connect(f"{address}?mode=ro", uri=True)
            try:
                db.execute("SELECT name FROM sqlite_master").fetchall()
            except sqlite3.OperationalError:
                if os.access(self.path.parent, os.W_OK):
                    raise
                db.close()
                db = connect(f"{address}?immutable=1", uri=True)
        db.execute("PRAGMA busy_timeout = 10000")
        return db

    def _create(self, plan: StudyPlan) -> None:
        self._db.execute("PRAGMA journal_mode = WAL")
        with self._transaction() as db:
            for statement in filter(str.strip, _SCHEMA.split(";")):
                db.execute(statement)
            db.executemany("INSERT INTO meta VALUES (?, ?)", [
                ("format", STORE_FORMAT), ("version", str(STORE_VERSION)), ("design", plan.design),
                ("plan_sha256", plan.sha256), ("plan", _plan_text(plan)), ("conditions", ",".join(plan.conditions)),
                ("trials", str(len(plan.trials))), ("created", _now())])

    @contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        """One write transaction (BEGIN IMMEDIATE ... COMMIT, or ROLLBACK on any error)."""
        with self._lock:
            self._db.execute("PRAGMA journal_mode = WAL")
            self._db.execute("PRAGMA synchronous = FULL")
            self._db.execute("BEGIN IMMEDIATE")
            try:
                yield self._db
                self._db.execute("COMMIT")
            except BaseException:
                if self._db.in_transaction:  # SQLite may have rolled back already (a full disk does)
                    self._db.execute("ROLLBACK")
                raise

    def close(self) -> None:
        with self._lock:
            self._db.close()

    # participants ----------------------------------------------------------------------------------------------
    def new_participant(self) -> str:
        """A new anonymous participant with their own order of trials; their ID."""
        if self.plan is None:
            raise ConfigError("this store was opened without its plan: it cannot take participants")
        with self._transaction() as db:
            ordinal = db.execute("SELECT COALESCE(MAX(ordinal), 0) + 1 FROM participants").fetchone()[0]
            participant = "P" + secrets.token_hex(6)
            code = secrets.token_hex(4).upper()
            db.execute("INSERT INTO participants VALUES (?, ?, ?, ?, NULL)", (participant, ordinal, code, _now()))
            db.executemany("INSERT INTO trials VALUES (?, ?, ?, ?, ?, ?)", [
                (participant, position, trial.order, trial.stimulus, trial.conditions[0],
                 trial.conditions[1] if len(trial.conditions) > 1 else None)
                for position, trial in enumerate(participant_trials(self.plan, ordinal), start=1)])
        return participant

    def _participant(self, participant: object) -> tuple:
        if not isinstance(participant, str) or not participant or len(participant) > 64:
            raise StudyStoreError("not a participant ID", status=404)
        row = self._db.execute("SELECT ordinal, code, finished FROM participants WHERE id = ?",
                               (participant,)).fetchone()
        if row is None:
            raise StudyStoreError(f"{participant[:64]!r} is not a participant of this study", status=404)
        return row

    def state(self, participant: object) -> dict:
        """Where ``participant`` is: ``{"participant", "answered", "total", "finished", "code"?, "trial"?}``;
        ``trial`` (the next one): ``{"position", "stimulus", "conditions": [...]}``."""
        with self._lock:
            _, code, finished = self._participant(participant)
            answered = self._db.execute("SELECT COUNT(*) FROM answers WHERE participant = ?",
                                        (participant,)).fetchone()[0]
            state: dict = {"participant": participant, "answered": answered, "total": self.total,
                           "finished": finished is not None}
            if finished is not None:
                state["code"] = code
                return state
            row = self._db.execute(
                "SELECT position, stimulus, first, second FROM trials WHERE participant = ? AND position NOT IN "
                "(SELECT position FROM answers WHERE participant = ?) ORDER BY position LIMIT 1",
                (participant, participant)).fetchone()
            state["trial"] = {"position": row[0], "stimulus": row[1],
                              "conditions": [name for name in row[2:] if name is not None]}
            return state

    def answer(self, participant: object, position: object, answer: object, seconds: object = None) -> dict:
        """Record ``answer`` to trial ``position`` of ``participant`` in one transaction; the new state.

        ``answer``: ``left`` or ``right`` (paired), a whole number 1-5 (mos), a condition name
        (identification). Answering the trial already answered with the same answer changes nothing.
        """
        with self._lock:
            self._participant(participant)
        if isinstance(position, bool) or not isinstance(position, int) or not 1 <= position <= self.total:
            raise StudyStoreError(f"the trial position must be a whole number from 1 to {self.total}")
        given = self._check_answer(answer)
        if isinstance(seconds, bool) or not isinstance(seconds, (int, float)) or not 0 <= seconds < 1e6:
            seconds = None
        with self._transaction() as db:
            _, _, finished = self._participant(participant)
            before = db.execute("SELECT answer FROM answers WHERE participant = ? AND position = ?",
                                (participant, position)).fetchone()
            if before is not None:
                if before[0] != given:
                    raise StudyStoreError(f"trial {position} was already answered ({before[0]})", status=409)
            else:
                nxt = db.execute("SELECT MIN(position) FROM trials WHERE participant = ? AND position NOT IN "
                                 "(SELECT position FROM answers WHERE participant = ?)",
                                 (participant, participant)).fetchone()[0]
                if nxt is None or position != nxt:
                    raise StudyStoreError(f"trial {position} is not the next one (that is {nxt})", status=409)
                db.execute("INSERT INTO answers VALUES (?, ?, ?, ?, ?)",
                           (participant, position, given, seconds, _now()))
                if nxt == self.total and finished is None:
                    db.execute("UPDATE participants SET finished = ? WHERE id = ?", (_now(), participant))
        return self.state(participant)

    def _check_answer(self, answer: object) -> str:
        if self.design == "paired":
            if answer in ("left", "right"):
                return str(answer)
            raise StudyStoreError("the answer must be left or right")
        if self.design == "mos":
            if not isinstance(answer, bool) and isinstance(answer, (int, str)) and str(answer) in map(str, SCORES):
                return str(answer)
            raise StudyStoreError("the answer must be a score from 1 to 5")
        if isinstance(answer, str) and answer in self.conditions:
            return answer
        raise StudyStoreError(f"the answer must be one of {', '.join(self.conditions)}")

    # the organiser's view --------------------------------------------------------------------------------------
    def progress(self) -> dict:
        """``{"participants", "finished", "answers"}``."""
        with self._lock:
            started, finished = self._db.execute(
                "SELECT COUNT(*), COUNT(finished) FROM participants").fetchone()
            answers = self._db.execute("SELECT COUNT(*) FROM answers").fetchone()[0]
        return {"participants": started, "finished": finished, "answers": answers, "trials_each": self.total}

    def export_rows(self) -> list[dict[str, str | int]]:
        """Every answer as a ballot row of the design (and ``order``, the plan's trial number), by participant
        number and position."""
        with self._lock:
            rows = self._db.execute(
                "SELECT t.stimulus, t.participant, t.first, t.second, a.answer, t.plan_order FROM answers a "
                "JOIN trials t ON t.participant = a.participant AND t.position = a.position "
                "JOIN participants p ON p.id = a.participant ORDER BY p.ordinal, a.position").fetchall()
        columns = EXPORT_COLUMNS[self.design]
        out = []
        for stimulus, subject, first, second, answer, order in rows:
            values = {"paired": (first, second, answer), "mos": (first, answer), "identification": (first, answer)}
            out.append({"stimulus": stimulus, "subject": subject,
                        **dict(zip(columns[2:], values[self.design], strict=True)), "order": order})
        return out

    def export_csv(self) -> str:
        """:meth:`export_rows` as the CSV text ``prosody study analyze`` reads.

        Raises
        ------
        ConfigError
            The database is damaged (a table or a column missing, unreadable pages).
        """
        buffer = io.StringIO()
        try:
            writer = csv.DictWriter(buffer, fieldnames=[*EXPORT_COLUMNS[self.design], "order"],
                                    lineterminator="\n")
            writer.writeheader()
            writer.writerows(self.export_rows())
        except (sqlite3.DatabaseError, KeyError, IndexError) as error:
            raise ConfigError(f"{self.path}: the study database is damaged ({error!s:.200})") from None
        return buffer.getvalue()


def _plan_text(plan: StudyPlan) -> str:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=["order", "stimulus", *CONDITION_COLUMNS[plan.design]],
                            lineterminator="\n")
    writer.writeheader()
    writer.writerows(plan.rows)
    return buffer.getvalue()
