"""The running study without a browser: its videos, its database of answers and its HTTP server, including
what goes wrong (answers out of turn, twice, from another site, on a full disk, a database of another kind)."""

from __future__ import annotations

import csv
import io
import json
import sqlite3
import threading
import urllib.error
import urllib.request
from pathlib import Path

import pytest
import soundfile
from conftest import REPO

from prosody.cli import main
from prosody.errors import ConfigError
from prosody.evaluation.preview import find_ffmpeg
from prosody.study.designs import make_plan, parse_plan
from prosody.study.stimuli import BUILT_IN, StudyCondition, check_stimuli, make_stimuli
from prosody.study.store import StudyStore, StudyStoreError

needs_ffmpeg = pytest.mark.skipif(find_ffmpeg() is None, reason="needs ffmpeg (pip install imageio-ffmpeg)")


def _plan(design: str = "paired", conditions=("none", "speech"), stimuli=("a", "b")):
    rows = make_plan(list(stimuli), design=design, conditions=list(conditions), seed=1)
    columns = list(rows[0])
    return parse_plan(",".join(columns) + "\n" + "".join(",".join(str(r[c]) for c in columns) + "\n" for r in rows))


# the database -----------------------------------------------------------------------------------------------------


def test_answers_count_once_and_in_turn(tmp_path) -> None:
    plan = _plan()  # 2 stimuli x 4 ordered pairs
    store = StudyStore(tmp_path / "s.sqlite", plan)
    who = store.new_participant()
    state = store.state(who)
    assert (state["answered"], state["total"], state["finished"]) == (0, 8, False)
    assert state["trial"]["position"] == 1
    with pytest.raises(StudyStoreError, match="not the next one") as caught:
        store.answer(who, 2, "left")
    assert caught.value.status == 409
    assert store.answer(who, 1, "left")["answered"] == 1
    assert store.answer(who, 1, "left")["answered"] == 1  # the same answer again: counted once
    with pytest.raises(StudyStoreError, match="already answered"):
        store.answer(who, 1, "right")
    with pytest.raises(StudyStoreError, match="left or right"):
        store.answer(who, 2, "middle")
    with pytest.raises(StudyStoreError, match="not a participant") as caught:
        store.state("P000000000000")
    assert caught.value.status == 404
    for position in range(2, 9):
        state = store.answer(who, position, "right")
    assert state["finished"] and len(state["code"]) == 8 and "trial" not in state
    rows = list(csv.DictReader(io.StringIO(store.export_csv())))
    assert len(rows) == 8 and [r["choice"] for r in rows] == ["left"] + ["right"] * 7
    assert sorted(int(r["order"]) for r in rows) == list(range(1, 9))
    store.close()
    # opened again (a restart): the same participant, the same answers
    again = StudyStore(tmp_path / "s.sqlite", plan)
    assert again.state(who)["finished"] and again.progress() == {"participants": 1, "finished": 1, "answers": 8,
                                                                 "trials_each": 8}
    again.close()


def test_many_participants_at_once_get_their_own_numbers(tmp_path) -> None:
    plan = _plan("mos", ("none", "speech", "random"))
    store = StudyStore(tmp_path / "s.sqlite", plan)
    found: list[str] = []

    def arrive() -> None:
        for _ in range(5):
            who = store.new_participant()
            found.append(who)
            store.answer(who, 1, 3)

    threads = [threading.Thread(target=arrive) for _ in range(8)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(set(found)) == 40
    ordinals = [row[0] for row in store._db.execute("SELECT ordinal FROM participants ORDER BY ordinal")]
    assert ordinals == list(range(1, 41))
    rows = list(csv.DictReader(io.StringIO(store.export_csv())))
    assert len(rows) == 40 and {r["score"] for r in rows} == {"3"}
    store.close()


def test_a_full_disk_loses_nothing_and_says_so(tmp_path) -> None:
    plan = _plan()
    store = StudyStore(tmp_path / "s.sqlite", plan)
    who = store.new_participant()
    store.answer(who, 1, "left")
    pages = store._db.execute("PRAGMA page_count").fetchone()[0]
    store._db.execute(f"PRAGMA max_page_count = {pages}")  # the database cannot grow: as on a full disk
    with pytest.raises(sqlite3.OperationalError, match="full"):
        for _ in range(200):  # participants until the free space is used up
            before = store.progress()
            store.new_participant()
    assert store.progress() == before  # the failed arrival left nothing behind
    trials = store._db.execute("SELECT COUNT(*) FROM trials").fetchone()[0]
    assert trials == 8 * before["participants"]  # and no participant is without their trials
    store._db.execute("PRAGMA max_page_count = 1000000")
    assert store.answer(who, 2, "right")["answered"] == 2  # and the study goes on once there is room
    store.close()


def test_a_database_that_is_not_this_studys_is_refused(tmp_path) -> None:
    plan = _plan()
    text = tmp_path / "notes.sqlite"
    text.write_text("hello, this is not a database at all" * 40)
    with pytest.raises(ConfigError, match="not a study database"):
        StudyStore(text, plan)
    other = tmp_path / "other.sqlite"
    with sqlite3.connect(other) as db:
        db.execute("CREATE TABLE customers (id INTEGER)")
    with pytest.raises(ConfigError, match="not a study database of this project"):
        StudyStore(other, plan)
    StudyStore(tmp_path / "s.sqlite", plan).close()
    with pytest.raises(ConfigError, match="another plan"):
        StudyStore(tmp_path / "s.sqlite", _plan(stimuli=("a", "c")))
    with pytest.raises(ConfigError, match="no such study database"):
        StudyStore(tmp_path / "missing.sqlite", create=False)
    assert main(["study", "export", str(text), "-o", str(tmp_path / "b.csv")]) == 2
    assert not (tmp_path / "b.csv").exists()


@pytest.mark.parametrize("damage, message", [
    ("DROP TABLE answers", "the study database is damaged"),
    ("DELETE FROM meta WHERE key = 'design'", "its record of the study lacks design"),
    ("UPDATE meta SET value = 'many' WHERE key = 'trials'", "lacks a trial count"),
    ("ALTER TABLE participants RENAME TO people", "the study database is damaged"),
])
def test_a_damaged_database_is_one_line_on_export(tmp_path, capsys, damage, message) -> None:
    path = tmp_path / "s.sqlite"
    store = StudyStore(path, _plan())
    who = store.new_participant()
    store.answer(who, 1, "left")
    store.close()
    with sqlite3.connect(path) as db:
        db.execute(damage)
    assert main(["study", "export", str(path), "-o", str(tmp_path / "b.csv")]) in (1, 2)
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "b.csv").exists()


def test_export_reads_the_database_without_writing_it(tmp_path) -> None:
    # export opens the database read-only: it works on media that cannot be written, and changes nothing
    path = tmp_path / "s.sqlite"
    store = StudyStore(path, _plan())
    store.answer(store.new_participant(), 1, "right")
    store.close()
    for leftover in tmp_path.glob("s.sqlite-*"):
        leftover.unlink()
    before = path.read_bytes()
    reader = StudyStore(path, create=False)
    with pytest.raises(sqlite3.OperationalError, match="readonly"):
        reader._db.execute("INSERT INTO meta VALUES ('x', 'y')")
    assert "right" in reader.export_csv()
    reader.close()
    assert path.read_bytes() == before


# the videos -------------------------------------------------------------------------------------------------------


def _recordings(where: Path) -> Path:
    folder = where / "recordings"
    folder.mkdir()
    samples, rate = soundfile.read(REPO / "samples" / "arctic_a0009.wav")
    for name, gain in (("a", 1.0), ("b", 0.5)):
        soundfile.write(folder / f"{name}.wav", gain * samples, rate)
    return folder


@pytest.fixture
def recordings(tmp_path):
    return _recordings(tmp_path)


def _conditions(plan):
    from prosody.cli.study import study_conditions as _study_conditions

    return _study_conditions(plan, None)


@pytest.mark.slow
@needs_ffmpeg
def test_stimuli_are_made_once_and_checked(tmp_path, recordings) -> None:
    plan = _plan()
    made: list[tuple[str, str, bool]] = []
    manifest = make_stimuli(plan, recordings, tmp_path / "stimuli", _conditions(plan), width=64,
                            on_video=lambda s, c, drawn: made.append((s, c, drawn)))
    assert sorted(manifest["videos"]) == ["a/NO_PROSODY", "a/SPEECH_DRIVEN", "b/NO_PROSODY", "b/SPEECH_DRIVEN"]
    assert all(drawn for _, _, drawn in made)
    assert (tmp_path / "stimuli" / "a" / "SPEECH_DRIVEN.mp4").stat().st_size > 1000
    assert check_stimuli(plan, tmp_path / "stimuli")["plan_sha256"] == plan.sha256
    made.clear()
    make_stimuli(plan, recordings, tmp_path / "stimuli", _conditions(plan), width=64,
                 on_video=lambda s, c, drawn: made.append((s, c, drawn)))
    assert not any(drawn for _, _, drawn in made)  # nothing changed: nothing drawn again
    (tmp_path / "stimuli" / "b" / "NO_PROSODY.mp4").unlink()
    with pytest.raises(ConfigError, match=r"1 video\(s\) of the plan are missing \(b/NO_PROSODY\)"):
        check_stimuli(plan, tmp_path / "stimuli")
    with pytest.raises(ConfigError, match="another plan"):
        check_stimuli(_plan(stimuli=("a", "c")), tmp_path / "stimuli")


def test_stimuli_inputs_are_checked_before_drawing(tmp_path, recordings) -> None:
    plan = _plan(conditions=("none", "truth", "calm"))
    with pytest.raises(ConfigError, match="calm that are not defined"):
        make_stimuli(plan, recordings, tmp_path / "out", {n: StudyCondition(n, n, BUILT_IN["NO_PROSODY"])
                                                          for n in ("NO_PROSODY", "GROUND_TRUTH")})
    conditions = {"NO_PROSODY": StudyCondition("NO_PROSODY", "x", {"condition": "none"}),
                  "GROUND_TRUTH": StudyCondition("GROUND_TRUTH", "x", {"condition": "truth"}),
                  "calm": StudyCondition("calm", "x", {"condition": "speech"})}
    with pytest.raises(ConfigError, match=r"no recorded motion (a|b).head.csv .*no recorded motion (a|b).head.csv"):
        make_stimuli(plan, recordings, tmp_path / "out", conditions)
    with pytest.raises(ConfigError, match="no recording c.wav"):
        make_stimuli(_plan(stimuli=("a", "c")), recordings, tmp_path / "out", _conditions(_plan()))
    assert not (tmp_path / "out").exists()  # nothing was started


def test_condition_files_take_convert_options(tmp_path, capsys) -> None:
    from prosody.cli.study import study_conditions as _study_conditions

    plan = _plan(conditions=("none", "calm"))
    path = tmp_path / "c.json"
    path.write_text(json.dumps({"format": "visual-prosody-study-conditions", "version": 1, "conditions": {
        "calm": {"label": "Calm", "options": "--activation 0.4 --model arx --pad=0.5,-0.3,0"}}}))
    conditions = _study_conditions(plan, str(path))
    calm = conditions["calm"]
    assert calm.label == "Calm" and calm.settings["model"] == "arx"
    assert calm.settings["expressivity"].activation == 0.4 and calm.settings["pad"] == "0.5,-0.3,0"
    assert conditions["NO_PROSODY"].settings["condition"] == "none"
    for options, message in (("--activation 2", "condition calm: argument --activation"),
                             ("--ground-truth x.csv", "found per stimulus"),
                             ("--frobnicate", "unrecognized arguments: --frobnicate"),
                             ("--condition none --model arx", "--model is the head model")):
        path.write_text(json.dumps({"format": "visual-prosody-study-conditions", "version": 1,
                                    "conditions": {"calm": {"options": options}}}))
        with pytest.raises(ConfigError, match=message):
            _study_conditions(plan, str(path))
    path.write_text(json.dumps({"format": "something-else", "conditions": {}}))
    with pytest.raises(ConfigError, match="not a study conditions file"):
        _study_conditions(plan, str(path))
    with pytest.raises(ConfigError, match="define it in a conditions file"):
        _study_conditions(plan, None)


def test_condition_files_take_settings_and_the_library_reads_them(tmp_path) -> None:
    """A condition's settings are data the library checks by its own rules, so a study runs from Python; the
    same rule refuses the same mistake given as options or as settings."""
    from prosody.study.stimuli import study_conditions

    plan = _plan(conditions=("none", "truth", "calm"))
    path = tmp_path / "c.json"

    def conditions(entry: dict) -> dict:
        path.write_text(json.dumps({"format": "visual-prosody-study-conditions", "version": 1,
                                    "conditions": {"calm": entry}}))
        return study_conditions(plan, path)

    calm = conditions({"label": "Calm", "settings": {"expressivity": {"activation": 0.4}, "pad": "0.5,-0.3,0",
                                                     "eyebrow_rule": {"rule": "accent", "threshold_semitones": 3},
                                                     "fps": 25}})["calm"]
    assert calm.settings["expressivity"].activation == 0.4 and calm.settings["condition"] == "speech"
    assert calm.settings["eyebrow_rule"].threshold_semitones == 3 and calm.settings["fps"] == 25
    built_in = study_conditions(plan, path)
    assert built_in["NO_PROSODY"].settings == {"condition": "none"} and built_in["GROUND_TRUTH"].needs_truth
    assert json.loads(calm.recipe)["pad"] == "0.5,-0.3,0"  # what the manifest records
    for settings, message in (({"condition": "none", "model": "arx"}, "condition calm: model= is the head model"),
                              ({"fpss": 25}, "unexpected keyword argument 'fpss'"),
                              ({"ground_truth": "x.csv"}, "found per stimulus"),
                              ({"eyebrow_rule": {"rule": "loud"}}, "eyebrow_rule needs"),
                              ({"expressivity": {"activation": 2}}, "activation"),
                              ({"lips": "acoustic", "transcript": "hello"}, "transcript= is read by the visemes")):
        with pytest.raises(ConfigError, match=message):
            conditions({"settings": settings})
    with pytest.raises(ConfigError, match="given as command-line options"):
        conditions({"options": "--activation 0.4"})  # options are the command's to read
    with pytest.raises(ConfigError, match="\"settings\" or \"options\""):
        conditions({"options": "--activation 0.4", "settings": {}})


# the server -------------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def served_stimuli(tmp_path_factory):
    """One plan's stimuli for every test of a server (they only read them): made once per module."""
    if find_ffmpeg() is None:
        pytest.skip("needs ffmpeg (pip install imageio-ffmpeg)")
    where = tmp_path_factory.mktemp("served")
    plan = _plan("identification", ("none", "speech"))
    make_stimuli(plan, _recordings(where), where / "stimuli", _conditions(plan), width=64)
    return plan, where / "stimuli"


@pytest.fixture
def served(tmp_path, served_stimuli):
    """A study server of its own (its own database, settings a test may change) on the shared stimuli."""
    from prosody.study.server import StudyServer

    plan, stimuli = served_stimuli
    store = StudyStore(tmp_path / "s.sqlite", plan)
    lines: list[str] = []
    server = StudyServer(plan, stimuli, store, port=0, token="secret-token", report=lines.append).start()
    server.lines = lines
    yield server
    server.close()
    store.close()


def _request(server, path: str, body: dict | None = None, headers: dict | None = None, data: bytes | None = None):
    request = urllib.request.Request(server.url.rstrip("/") + path, method="POST" if body or data else "GET",
                                     data=data if data is not None else (json.dumps(body).encode() if body else None),
                                     headers={"Content-Type": "application/json", **(headers or {})})
    try:
        with urllib.request.urlopen(request, timeout=10) as response:
            return response.status, response.read(), dict(response.headers)
    except urllib.error.HTTPError as error:
        return error.code, error.read(), dict(error.headers)


def test_server_round_trip_and_refusals(served) -> None:
    status, body, headers = _request(served, "/")
    assert status == 200 and b"studyState" in body and "default-src 'self'" in headers["Content-Security-Policy"]
    info = json.loads(_request(served, "/api/study")[1])
    assert info["design"] == "identification" and [o["name"] for o in info["options"]] == ["NO_PROSODY",
                                                                                          "SPEECH_DRIVEN"]
    status, body, _ = _request(served, "/api/participants", {"start": True})
    state = json.loads(body)
    assert status == 201 and state["trial"]["position"] == 1
    video = state["trial"]["videos"][0]
    assert "NO_PROSODY" not in video and "SPEECH" not in video  # the address does not give the answer away
    status, clip, _ = _request(served, video)
    assert status == 200 and clip[4:8] == b"ftyp"
    status, part, headers = _request(served, video, headers={"Range": "bytes=10-19"})
    assert status == 206 and part == clip[10:20] and headers["Content-Range"] == f"bytes 10-19/{len(clip)}"
    assert _request(served, "/stimuli/../s.sqlite")[0] == 404
    assert _request(served, "/stimuli/a/NO_PROSODY.mp4")[0] == 404  # only the served names
    who = state["participant"]
    status, body, _ = _request(served, "/api/answer", {"participant": who, "position": 1, "answer": "SPEECH_DRIVEN"})
    assert status == 200 and json.loads(body)["answered"] == 1
    assert _request(served, "/api/answer", {"participant": "Pnobody", "position": 1, "answer": "x"})[0] == 404
    assert _request(served, "/api/answer", {"participant": who, "position": 2, "answer": "joy"})[0] == 400
    # not JSON, too big, from another site
    assert _request(served, "/api/answer", data=b"participant=x", headers={"Content-Type": "text/plain"})[0] == 415
    assert _request(served, "/api/answer", data=b"{" + b" " * 5000 + b"}")[0] == 413
    status, _, _ = _request(served, "/api/participants", {"start": True}, headers={"Origin": "https://evil.example"})
    assert status == 403 and any("refused a request from 'https://evil.example'" in line for line in served.lines)
    status, _, _ = _request(served, "/api/study", headers={"Host": "rebind.example:80"})
    assert status == 403  # a name another site's DNS could point here
    own = served.url.rstrip("/")
    assert _request(served, "/api/participants", {"start": True}, headers={"Origin": own})[0] == 201
    # the organiser's export needs the token
    assert _request(served, "/admin/export.csv")[0] == 401
    assert _request(served, "/admin/export.csv?token=wrong")[0] == 401
    status, body, _ = _request(served, "/admin/export.csv", headers={"Authorization": "Bearer secret-token"})
    rows = list(csv.DictReader(io.StringIO(body.decode())))
    assert status == 200 and len(rows) == 1 and rows[0]["answer"] == "SPEECH_DRIVEN" and rows[0]["subject"] == who
    progress = json.loads(_request(served, "/admin/progress?token=secret-token")[1])
    assert progress == {"participants": 2, "finished": 0, "answers": 1, "trials_each": 4}


def test_server_says_503_when_the_answer_cannot_be_saved(served) -> None:
    who = json.loads(_request(served, "/api/participants", {"start": True})[1])["participant"]
    store = served.store
    served.arrivals.per_client = 100  # this test makes participants until the disk is full
    pages = store._db.execute("PRAGMA page_count").fetchone()[0]
    store._db.execute(f"PRAGMA max_page_count = {pages}")
    for _ in range(30):  # fill the last free pages
        status, body, _ = _request(served, "/api/participants", {"start": True})
        if status == 503:
            break
    assert status == 503 and b"could not be saved" in body
    answered = store.progress()["answers"]
    store._db.execute("PRAGMA max_page_count = 1000000")
    status, body, _ = _request(served, "/api/answer", {"participant": who, "position": 1, "answer": "NO_PROSODY"})
    assert status == 200 and store.progress()["answers"] == answered + 1


@needs_ffmpeg
def test_a_refused_start_leaves_no_database(tmp_path, recordings, capsys) -> None:
    import socket

    plan_path = tmp_path / "plan.csv"
    assert main(["study", "plan", "--stimuli", "a", "--conditions", "none,speech", "-o", str(plan_path)]) == 0
    assert main(["study", "stimuli", str(plan_path), "--recordings", str(recordings), "--width", "64",
                 "-o", str(tmp_path / "stimuli")]) == 0
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert main(["study", "serve", str(plan_path), "--stimuli", str(tmp_path / "stimuli"), "--db",
                     str(tmp_path / "s.sqlite"), "--listen", f"127.0.0.1:{port}"]) == 2
    assert "cannot listen on" in capsys.readouterr().err
    other = tmp_path / "other.csv"
    assert main(["study", "plan", "--stimuli", "b", "--conditions", "none,speech", "-o", str(other)]) == 0
    assert main(["study", "serve", str(other), "--stimuli", str(tmp_path / "stimuli"), "--db",
                 str(tmp_path / "s.sqlite")]) == 2
    assert "made for another plan" in capsys.readouterr().err
    assert not list(tmp_path.glob("s.sqlite*"))


@pytest.mark.slow
# what an outside probe broke ---------------------------------------------------------------------------------
@needs_ffmpeg
def test_a_manifest_may_only_name_videos_in_its_folder_and_each_entry_is_checked(tmp_path, recordings,
                                                                                  capsys) -> None:
    from prosody.study.ballots import write_plan
    from prosody.study.server import StudyServer

    write_plan(make_plan(["a", "b"], design="paired", conditions=["none", "speech"], seed=1), tmp_path / "plan.csv")
    plan = _plan()
    folder = tmp_path / "stimuli"
    make_stimuli(plan, recordings, folder, _conditions(plan), width=64)
    original = (folder / "stimuli.json").read_text()
    store = StudyStore(tmp_path / "s.sqlite", plan)
    (tmp_path / "secret.txt").write_text("secret")
    (folder / "a" / "link.mp4").symlink_to(tmp_path / "secret.txt")
    bad_entries = {
        "/etc/passwd": (lambda entry: entry | {"file": "/etc/passwd"}, "outside"),
        "../": (lambda entry: entry | {"file": "../secret.txt"}, "outside"),
        "a link out": (lambda entry: entry | {"file": "a/link.mp4"}, "outside"),
        "not an object": (lambda entry: ["a/NO_PROSODY.mp4"], "is not an object"),
        "no sha256": (lambda entry: {"file": entry["file"]}, "is not an object with a file name and its SHA-256"),
    }
    for name, (change, message) in bad_entries.items():
        manifest = json.loads(original)
        manifest["videos"]["a/NO_PROSODY"] = change(manifest["videos"]["a/NO_PROSODY"])
        (folder / "stimuli.json").write_text(json.dumps(manifest))
        with pytest.raises(ConfigError, match=message):
            StudyServer(plan, folder, store, port=0)
        capsys.readouterr()
        assert main(["study", "serve", str(tmp_path / "plan.csv"), "--stimuli", str(folder), "--db",
                     str(tmp_path / "s.sqlite"), "--listen", "127.0.0.1:0"]) != 0, name
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    store.close()


def _open_connections(served, count: int, payload: bytes) -> list:
    import socket

    host, port = served._http.server_address[:2]
    sockets = []
    for _ in range(count):
        connection = socket.create_connection((host, port), timeout=10)
        connection.sendall(payload)
        sockets.append(connection)
    return sockets


def test_ranges_are_read_by_seeking_not_the_whole_video(served) -> None:
    import tracemalloc

    state = json.loads(_request(served, "/api/participants", {"start": True})[1])
    video = state["trial"]["videos"][0]
    path = served.files[video.rsplit("/", 1)[1]]
    head = path.read_bytes()[:20]
    with open(path, "r+b") as handle:  # a 64 MB video (its tail sparse)
        handle.truncate(64 << 20)
    tracemalloc.start()
    try:
        for _ in range(10):
            status, part, headers = _request(served, video, headers={"Range": "bytes=0-1"})
            assert status == 206 and part == head[:2] and headers["Content-Range"] == f"bytes 0-1/{64 << 20}"
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 4 << 20  # the whole file each time was 64 MB a request
    status, part, headers = _request(served, video, headers={"Range": "bytes=-5"})
    size = 64 << 20
    assert status == 206 and part == b"\0" * 5 and headers["Content-Range"] == f"bytes {size - 5}-{size - 1}/{size}"
    status, _, _ = _request(served, video, headers={"Range": "bytes=" + "9" * 5000 + "-"})
    assert status == 200  # not a range this server reads: the whole video, no traceback


def test_many_voters_at_once_are_all_served(served) -> None:
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(50) as pool:
        statuses = list(pool.map(lambda _: _request(served, "/api/study")[0], range(50)))
    assert statuses == [200] * 50


@pytest.mark.slow
def test_half_sent_requests_are_timed_out_and_bounded_and_told_in_one_line(served, capfd) -> None:
    import time

    from prosody.study.server import MAX_HANDLERS

    served._http.RequestHandlerClass.timeout = 1.0
    before = threading.active_count()
    stalled = _open_connections(served, 100, b"GET /api/study HTTP/1.1\r\nHost: 127.0.0.1\r\n")
    time.sleep(0.5)
    assert threading.active_count() - before <= MAX_HANDLERS
    deadline = time.monotonic() + 30
    status = None
    while time.monotonic() < deadline and status != 200:  # served once the stalled ones are let go
        status = _request(served, "/api/study")[0]
        assert status in (200, 503)
    assert status == 200
    for connection in stalled:  # each closed by the server once silent too long, or told to come back
        connection.settimeout(10)
        try:
            answer = connection.recv(100)
        except ConnectionResetError:
            answer = b""
        assert answer == b"" or answer.startswith(b"HTTP/1.1 503"), answer
        connection.close()
    # a client that goes away mid-answer: one line, no traceback
    gone = _open_connections(served, 1, b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")[0]
    gone.close()
    time.sleep(0.3)
    assert "Traceback" not in capfd.readouterr().err


def test_new_participants_are_limited_per_address_and_the_counterbalancing_is_kept(served) -> None:
    from prosody.study.server import NEW_PER_CLIENT_PER_MINUTE

    statuses = [_request(served, "/api/participants", {"start": True})[:3:2] for _ in range(15)]
    assert [status for status, _ in statuses] == [201] * NEW_PER_CLIENT_PER_MINUTE + [429] * 5
    assert statuses[-1][1]["Retry-After"] == "60"
    assert served.store.progress()["participants"] == NEW_PER_CLIENT_PER_MINUTE
    assert sum("refused a new participant" in line for line in served.lines) == 1  # one line a second at most


def test_an_answer_position_out_of_range_is_a_400(served) -> None:
    who = json.loads(_request(served, "/api/participants", {"start": True})[1])["participant"]
    for position in (2**63, -1, 0, 10**30):
        status, body, _ = _request(served, "/api/answer", {"participant": who, "position": position, "answer": "x"})
        assert status == 400 and b"from 1 to 4" in body


@needs_ffmpeg
@pytest.mark.slow
def test_the_study_listens_on_ipv6(tmp_path, recordings) -> None:
    from prosody.study.server import StudyServer

    plan = _plan()
    make_stimuli(plan, recordings, tmp_path / "stimuli", _conditions(plan), width=64)
    store = StudyStore(tmp_path / "s.sqlite", plan)
    server = StudyServer(plan, tmp_path / "stimuli", store, host="::1", port=0).start()
    try:
        assert server.url.startswith("http://[::1]:")
        with urllib.request.urlopen(server.url + "api/study", timeout=10) as response:
            assert json.loads(response.read())["design"] == "paired"
    finally:
        server.close()
        store.close()


@pytest.mark.slow
@pytest.mark.parametrize("damage, said", [
    (lambda text: text[: len(text) // 2], "SHA-256"),  # cut short after the stimuli were made
    (None, "not head frames a page can play"),  # changed, and its hash with it: frames not one per FAP
])
def test_head_frames_that_fail_their_checks_leave_the_video_shown(tmp_path, recordings, damage, said) -> None:
    """A malformed <condition>.head.json left a participant a blank face (canvas inserted, video hidden) or a
    frozen head; the server never checked motion_sha256. Now each video's frames are checked at the start (hash,
    document, one finite number per FAP per frame, the video's length) and served from memory as checked; frames
    that fail are said in one line and that trial shows the video."""
    import hashlib

    if find_ffmpeg() is None:
        pytest.skip("needs ffmpeg (pip install imageio-ffmpeg)")
    from prosody.study.server import StudyServer

    plan = _plan("identification", ("none", "speech"))
    folder = tmp_path / "stimuli"
    make_stimuli(plan, recordings, folder, _conditions(plan), width=64)
    manifest_path = folder / "stimuli.json"
    manifest = json.loads(manifest_path.read_text())
    key, entry = next(iter(manifest["videos"].items()))
    motion = folder / entry["motion"]
    if damage is not None:
        motion.write_text(damage(motion.read_text()))
    else:  # well-formed JSON, hash recorded, but a frame missing a value
        document = json.loads(motion.read_text())
        document["frames"][3] = document["frames"][3][:-1] if document["faps"] else [1.0]
        motion.write_text(json.dumps(document))
        entry["motion_sha256"] = hashlib.sha256(motion.read_bytes()).hexdigest()
        manifest_path.write_text(json.dumps(manifest))
    store = StudyStore(tmp_path / "s.sqlite", plan)
    lines: list[str] = []
    server = StudyServer(plan, folder, store, port=0, token="t", report=lines.append).start()
    try:
        assert server.motions[key] is None
        assert any(key in line and said in line and "shown as recorded" in line for line in lines), lines
        others = [url for other, url in server.motions.items() if other != key]
        assert others and all(url is not None for url in others)
        status, body, headers = _request(server, others[0])  # the good ones are served as checked
        assert status == 200 and json.loads(body)["format"] == "visual-prosody-head-frames"
        assert headers["Content-Type"] == "application/json"
    finally:
        server.close()
        store.close()
