"""The command line as a user meets it: versions, pipes, standard output, conflicting options."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
import soundfile
from conftest import REPO, segments

from prosody import __version__
from prosody.cli import main

SR = 16000


def _run(*args: str, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "prosody", *args], capture_output=True, **kwargs)


def test_version_and_python_dash_m() -> None:
    result = _run("--version", text=True)
    assert result.returncode == 0 and result.stdout.strip() == f"prosody {__version__}"
    assert __version__ != "0+unknown"


def test_convert_to_standard_output_keeps_the_input_name(speech) -> None:
    result = _run("convert", str(speech), "-o", "-", "--format", "fap")
    assert result.returncode == 0
    lines = result.stdout.decode().splitlines()
    assert lines[0] == "2.1 speech 30 51" and len(lines) == 1 + 2 * 51
    assert main(["convert", str(speech), "-o", "-"]) == 2  # no format to write standard output in


def test_a_reader_that_goes_away_is_not_an_error(tmp_path, speech) -> None:
    fap = tmp_path / "s.fap"
    assert main(["convert", str(speech), "-o", str(fap)]) == 0
    inspect = subprocess.Popen([sys.executable, "-m", "prosody", "inspect", str(fap), "--json"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert inspect.stdout is not None
    inspect.stdout.read(10)
    inspect.stdout.close()  # as `| head -c 10` does
    _, err = inspect.communicate(timeout=60)
    assert inspect.returncode == 0 and b"Broken pipe" not in err and b"Traceback" not in err


@pytest.mark.parametrize("arguments, message", [
    (["--ground-truth", "x.head.csv"], "not used by --condition speech"),
    (["--off", "pitch,yaw", "--off", "roll,brows,lips"], "every channel"),
    (["--lips", "acoustic", "--transcript", "hello"], "not used by --lips acoustic"),
    (["--condition", "random", "--model", "arx"], "not used by --condition random"),
    (["--condition", "random", "--ground-truth", "x.head.csv"], "not used by --condition random"),
])
def test_options_that_would_silently_do_nothing_are_refused(tmp_path, speech, capsys, arguments, message) -> None:
    out = tmp_path / "x.fap"
    assert main(["convert", str(speech), "-o", str(out), *arguments]) == 2
    assert message in capsys.readouterr().err and not out.exists()


def test_features_are_written_as_csv_only(tmp_path, speech, capsys) -> None:
    assert main(["features", str(speech), "-o", str(tmp_path / "x.json")]) == 2
    assert ".csv" in capsys.readouterr().err and not (tmp_path / "x.json").exists()


def test_bvh_says_it_holds_the_head_only(tmp_path, speech, capsys) -> None:
    assert main(["convert", str(speech), "-o", str(tmp_path / "x.bvh")]) == 0
    assert "BVH holds the head only" in capsys.readouterr().err


def test_help_texts_stand_alone() -> None:
    from prosody.cli import build_parser

    parser = build_parser()
    texts = [parser.format_help()]
    for action in parser._subparsers._group_actions:  # noqa: SLF001 - every subcommand's help
        for name, sub in action.choices.items():
            texts.append(sub.format_help())
            if name == "study":
                texts += [step.format_help() for step in sub._subparsers._group_actions[0].choices.values()]
    joined = "\n".join(texts)
    assert "SPEC" not in joined and "%%" not in joined


def test_batch_with_a_file_name_that_is_not_utf8(tmp_path) -> None:
    if sys.platform == "darwin":
        pytest.skip("macOS file systems refuse names that are not UTF-8")
    indir = tmp_path / "in"
    indir.mkdir()
    soundfile.write(indir / "plain.wav", segments(SR, (0.6, 140, 0.5), (0.5, 230, 0.5)), SR)
    os.rename(os.fsencode(indir / "plain.wav"), os.fsencode(indir) + b"/take_\xff.wav")
    out = tmp_path / "out"
    assert main(["batch", str(indir), "-o", str(out), "--condition", "none", "--seeds", "1"]) == 0
    assert (out / "summary.md").exists() and (out / "summary.json").exists()
    assert b"take_\xff.wav" in (out / "summary.md").read_bytes()


def test_library_messages_name_python_arguments_and_the_command_names_its_options(tmp_path, speech, capsys) -> None:
    from prosody.errors import ConfigError
    from prosody.jobs.pipeline import convert

    with pytest.raises(ConfigError, match=r"output_format=NAME"):
        convert(speech, tmp_path / "x.unknown")
    assert main(["convert", str(speech), "-o", str(tmp_path / "x.unknown")]) == 2
    err = capsys.readouterr().err
    assert "--format NAME" in err and "output_format" not in err
    assert main(["convert", str(speech), "-o", str(tmp_path / "x.fap"), "--condition", "truth"]) == 2
    assert "--ground-truth FILE" in capsys.readouterr().err


@pytest.mark.parametrize("arguments, message", [
    (["convert", "{speech}", "-o", "{speech}", "--format", "fap"], "is also the input"),
    (["convert", "{speech}", "-o", "{dir}/../{dir_name}/speech.wav", "--format", "fap"], "is also the input"),
    (["convert", "{speech}", "-o", ""], "give a file name"),
    (["features", "{speech}", "-o", "   "], "give a file name"),
    (["study", "plan", "--stimuli", "a,b", "-o", "-"], "'prosody study plan' writes files"),
    (["train", "--data", "{dir}", "-o", "-"], "'prosody train' writes files"),
    (["compare", "{speech}", "-o", "-"], "'prosody compare' writes files"),
    (["study", "analyze", "{dir}/ballots.csv", "-o", "{dir}/r.json", "--report", "{dir}/r.json"], "is also -o"),
    (["study", "analyze", "{dir}/ballots.csv", "-o", "{dir}/ballots.csv"], "is also the input"),
])
def test_an_output_that_is_an_input_or_no_file_is_refused(tmp_path, speech, capsys, arguments, message) -> None:
    before = speech.read_bytes()
    (tmp_path / "ballots.csv").write_text("stimulus,subject,left,right,choice\n")
    argv = [a.format(speech=speech, dir=speech.parent, dir_name=speech.parent.name) for a in arguments]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert speech.read_bytes() == before
    assert (tmp_path / "ballots.csv").read_text() == "stimulus,subject,left,right,choice\n"
    assert not (tmp_path / "r.json").exists()


@pytest.mark.parametrize("command", ["convert", "preview"])
@pytest.mark.parametrize("option, content", [
    ("--transcript", "hello world\n"), ("--expression", "time_s,joy\n0,1\n"), ("--pad", "time_s,p,a,d\n0,0,0,0\n"),
    ("--pad-map", "{}\n"), ("--mouth-model", "{}\n")])
@pytest.mark.parametrize("link", ["same", "symlink", "hardlink"])
def test_no_output_is_a_file_any_option_reads(tmp_path, speech, capsys, command, option, content, link) -> None:
    given = tmp_path / "given.txt"
    given.write_text(content)
    out = given if link == "same" else tmp_path / "out.fap"
    if link == "symlink":
        out.symlink_to(given)
    elif link == "hardlink":
        os.link(given, out)
    assert main([command, str(speech), option, str(given), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"is also {option}: writing it would destroy it" in err and len(err.strip().splitlines()) == 1
    assert given.read_text() == content


def test_compare_refuses_an_input_inside_its_output_folder_under_a_name_it_writes(tmp_path, speech, capsys) -> None:
    out = tmp_path / "out"
    out.mkdir()
    truth = out / "ground_truth.fap"
    truth.write_text("x")
    assert main(["compare", str(speech), "--ground-truth", str(truth), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--ground-truth" in err and "under a name the command writes there" in err and truth.read_text() == "x"
    elsewhere = tmp_path / "take.fap"
    elsewhere.write_text("x")
    (out / "mine.fap").symlink_to(elsewhere)  # a link's own name is not written; its target is outside
    main(["compare", str(speech), "--ground-truth", str(out / "mine.fap"), "-o", str(out)])  # "x" is no FAP file
    assert "under a name the command writes" not in capsys.readouterr().err and elsewhere.read_text() == "x"


@pytest.mark.slow
def test_quiet_says_only_errors_and_json_messages_are_one_object_a_line(tmp_path, speech) -> None:
    import json

    out = tmp_path / "x.fap"
    quiet = _run("convert", str(speech), "-o", str(out), "--lips", "none", "--quiet", text=True)
    assert quiet.returncode == 0 and quiet.stderr == "" and out.exists()
    failing = _run("convert", str(speech), "-o", str(out), "--quiet", "--f0-floor", "5", text=True)
    assert failing.returncode == 2 and failing.stderr.count("\n") == 1 and "error" in failing.stderr
    machine = _run("convert", str(speech), "-o", str(out), "--lips", "none", "--messages", "json", text=True)
    events = [json.loads(line) for line in machine.stderr.splitlines()]
    assert {event["event"] for event in events} <= {"progress", "warning", "info"}
    progress = [e for e in events if e["event"] == "progress"]
    assert progress[-1]["done"] == progress[-1]["total"] == 51
    assert events[-1]["event"] == "info" and str(out) in events[-1]["message"]
    broken = _run("convert", str(speech), "-o", str(out), "--messages", "json", "--f0-floor", "5", text=True)
    assert [json.loads(line) for line in broken.stderr.splitlines()][-1]["exit"] == 2


@pytest.mark.parametrize("fps", ["1e-308", "5e-324", "0.5", "1001"])
@pytest.mark.parametrize("command", ["features", "convert", "preview", "stream", "compare", "batch", "train"])
def test_a_frame_rate_out_of_range_is_one_line_in_every_command(tmp_path, speech, capsys, command, fps) -> None:
    argv = {"train": ["train", "--data", str(tmp_path)], "batch": ["batch", str(tmp_path)]}.get(
        command, [command, str(speech)])
    with pytest.raises(SystemExit) as stop:
        main([*argv, "-o", str(tmp_path / "out.csv"), "--fps", fps])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "expected a number in [1, 1000]" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_the_library_refuses_a_frame_rate_below_one(speech) -> None:
    from audio_features import extract_features
    from audio_features.errors import ParameterError

    with pytest.raises(ParameterError, match="from 1 to 1000"):
        extract_features(speech, fps=1e-308)


def test_batch_warnings_name_batchs_own_options_not_python(tmp_path, capsys) -> None:
    import shutil

    from conftest import REPO

    folder = tmp_path / "in"
    folder.mkdir()
    shutil.copy(REPO / "samples" / "arctic_a0007.wav", folder)  # a low voice: no raise at the default threshold
    assert main(["batch", str(folder), "-o", str(tmp_path / "out"), "--condition", "speech", "--seeds", "1",
                 "--lips", "none"]) == 0
    err = capsys.readouterr().err
    # batch says the brows' threshold by the name every command gives it
    assert "no eyebrow raise" in err and "(--accent-semitones ST, default 4)" in err
    assert "AccentRule" not in err and "--brow-semitones" not in err
    assert main(["batch", str(folder), "-o", str(tmp_path / "out2"), "--condition", "speech", "--seeds", "1",
                 "--lips", "none", "--accent-semitones", "1"]) == 0
    assert "no eyebrow raise" not in capsys.readouterr().err
    # the old name still works, with a warning naming the new one
    assert main(["batch", str(folder), "-o", str(tmp_path / "out3"), "--condition", "speech", "--seeds", "1",
                 "--lips", "none", "--brow-semitones", "1"]) == 0
    err = capsys.readouterr().err
    assert "--brow-semitones is now --accent-semitones" in err and "no eyebrow raise" not in err
    assert main(["batch", str(folder), "-o", str(tmp_path / "out4"), "--brow-semitones", "1",
                 "--accent-semitones", "2"]) == 2


def test_main_leaves_the_process_as_it_found_it(tmp_path, speech, capsys) -> None:
    import signal

    from prosody.cli import messages

    def mine(signum, frame):
        pass

    before = signal.signal(signal.SIGTERM, mine)
    try:
        assert main(["convert", str(speech), "-o", str(tmp_path / "x.fap"), "--lips", "none", "--messages",
                     "json"]) == 0
        assert signal.getsignal(signal.SIGTERM) is mine  # the caller's handler is back
        assert messages.MESSAGES.mode == "text"  # and the message mode
    finally:
        signal.signal(signal.SIGTERM, before)
    capsys.readouterr()


CLI_MESSAGES = [
    ("convert", "f0_floor_hz must be below f0_ceiling_hz, got 500", ("f0_floor_hz", "f0_ceiling_hz"),
     "--f0-floor must be below --f0-ceiling, got 500"),
    ("compare", "needs recorded motion (ground_truth=FILE)", ("ground_truth",),
     "needs recorded motion (--ground-truth FILE)"),
    ("convert", "give output_format=NAME or a known ending", ("output_format",),
     "give --format NAME or a known ending"),
    ("stream", "from its extension (.fap); give output_format=NAME", (),  # a phrase: stream's option has another name
     "from its extension (.fap); give --format NAME"),
    ("preview", "start_s= and duration_s= lie outside the stream", ("start_s", "duration_s"),
     "--start and --duration lie outside the stream"),
    ("convert", "resampled to 30 fps (give fps=25 to keep its rate)", ("fps",),
     "resampled to 30 fps (give --fps 25 to keep its rate)"),
    ("convert", "seed must be a whole number; the model runs at fps 30", ("seed", "fps"),
     "seed must be a whole number; the model runs at fps 30"),
    ("batch", "AccentRule(threshold_semitones=...) is 4; scheduler= is down", ("scheduler",),
     "--accent-semitones ST is 4; --scheduler is down"),
    ("batch", "needs recorded motion (ground_truth=FILE)", ("ground_truth",),
     "needs recorded motion (ground_truth=FILE)"),  # batch has no such option
    ("convert", "/data/seed=3/a.wav: not found", ("seed",), "/data/seed=3/a.wav: not found"),  # a path is left alone
    ("convert", "'f0_floor_hz' and a.f0_floor_hz", ("f0_floor_hz",), "'f0_floor_hz' and a.f0_floor_hz"),
    # only the parameters the message carries as data are renamed, never a word that looks like one
    ("convert", "f0_floor_hz must be below f0_ceiling_hz", ("f0_ceiling_hz",),
     "f0_floor_hz must be below --f0-ceiling"),
    ("convert", "fps=25 and f0_floor_hz=50", (), "fps=25 and f0_floor_hz=50"),
]


@pytest.mark.parametrize(("command", "said", "parameters", "shown"), CLI_MESSAGES)
def test_library_messages_name_the_commands_options_from_its_parser(command, said, parameters, shown):
    import argparse

    from prosody.cli.app import build_parser
    from prosody.cli.messages import as_flags

    commands = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)).choices
    assert as_flags(said, commands[command], parameters) == shown


def test_an_error_carries_the_parameters_it_names_across_processes():
    import pickle

    from prosody.cli.app import build_parser
    from prosody.cli.messages import said
    from prosody.errors import ConfigError

    error = pickle.loads(pickle.dumps(ConfigError("f0_floor_hz=20 is too low", parameter="f0_floor_hz")))
    assert error.parameters == ("f0_floor_hz",)
    assert said(error, build_parser("convert")._subparsers._group_actions[0].choices["convert"]) == \
        "--f0-floor 20 is too low"


def test_a_library_message_reaches_the_user_with_the_option_names(tmp_path, capsys):
    wav = tmp_path / "tone.wav"
    soundfile.write(wav, segments(16000, (1.0, 150, 0.3)), 16000)
    code = main(["features", str(wav), "-o", str(tmp_path / "f.csv"), "--f0-floor", "400", "--f0-ceiling", "300"])
    error = capsys.readouterr().err
    assert code == 2 and "--f0-floor" in error and "f0_floor_hz" not in error


def test_an_unknown_option_is_named_by_its_command(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["convert", "speech.wav", "-o", "out.fap", "--fsp", "25"])
    assert stop.value.code == 2
    assert capsys.readouterr().err == ("prosody convert: error: unrecognized arguments: --fsp 25 (see 'prosody convert "
                                       "--help')\n")


def test_leaving_out_every_channel_is_the_librarys_rule(tmp_path, capsys) -> None:
    """An output with every moving channel left out is refused by the library (convert, compare, the live
    converter) and by the command line in the same words, with the command's own option."""
    from prosody import LiveConverter, compare, convert
    from prosody.errors import ConfigError

    every = ("pitch", "yaw", "roll", "brows", "lips")
    speech = REPO / "samples" / "arctic_a0009.wav"
    for call in (lambda: convert(speech, None, disabled=every), lambda: compare(speech, disabled=every),
                 lambda: LiveConverter(16000, disabled=every)):
        with pytest.raises(ConfigError, match="leaves out every channel") as refused:
            call()
        assert refused.value.parameters == ("disabled",)
    convert(speech, None, disabled=every[:4], lips=None, expression="joy:0.5")  # an expression still moves
    assert main(["convert", str(speech), "-o", str(tmp_path / "x.fap"), "--off", "pitch,yaw,roll,brows,lips"]) == 2
    assert "--off leaves out every channel" in capsys.readouterr().err
    assert not (tmp_path / "x.fap").exists()
