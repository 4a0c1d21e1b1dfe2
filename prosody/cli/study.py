"""``prosody study``: a perceptual study from plan to analysis (plan, stimuli, serve, export, analyze)."""

from __future__ import annotations

import argparse
import contextlib
import os

from . import messages as msg
from . import options as opt


def condition_names(text: str | None) -> list[str] | None:
    """--conditions of 'study plan': comma-separated names, where an item ending in .json is a conditions file
    standing for its names (in its order)."""
    if text is None:
        return None
    from ..study.stimuli import read_conditions

    names: list[str] = []
    for item in text.split(","):
        names += list(read_conditions(item.strip())) if item.strip().lower().endswith(".json") else [item]
    return names


def stimulus_names(given: str) -> list[str]:
    """``--stimuli``: names, comma-separated, or a folder of recordings (the stems of its WAV files)."""
    from pathlib import Path

    from ..errors import ConfigError

    if not os.path.isdir(given):  # (os.path's, which says False for a name too long to be a path)
        return given.split(",")
    folder = Path(given)
    names = sorted(path.stem for path in folder.iterdir() if path.suffix.lower() == ".wav" and path.is_file())
    if not names:
        raise ConfigError(f"--stimuli {given}: a folder with no recording (NAME.wav) in it")
    return names


def _recorded_motion_check(stimuli: list[str], given: str, conditions: list[str] | None) -> list[str] | None:
    """The conditions of the plan once the recordings of the folder ``given`` are known: the recorded-motion
    condition left out (said) where a recording has none and the conditions are the default ones, refused
    (naming the recordings) where it was asked for."""
    from pathlib import Path

    from ..errors import ConfigError
    from ..motion.conditions import Condition
    from ..study.designs import CONDITIONS
    from ..study.stimuli import find_truth

    if not os.path.isdir(given):
        return conditions

    def recorded(name: str) -> bool:
        try:
            return Condition.parse(name) is Condition.GROUND_TRUTH
        except ConfigError:
            return False

    wanted = [name for name in (conditions or CONDITIONS) if recorded(name)]
    without = [stimulus for stimulus in stimuli if find_truth(Path(given), stimulus) is None]
    if not wanted or not without:
        return conditions
    shown = ", ".join(without[:5]) + (f" and {len(without) - 5} more" if len(without) > 5 else "")
    if conditions is not None:
        raise ConfigError(f"--conditions {','.join(wanted)} plays recorded motion, which {shown} lack(s) "
                          f"(<stimulus>.head.csv or .fap beside the recording in {given})")
    msg.say(f"{given}: {shown} lack(s) recorded motion (<stimulus>.head.csv or .fap): the plan leaves "
            f"{','.join(wanted)} out")
    return [name for name in CONDITIONS if name not in wanted]


def run_plan(args: argparse.Namespace) -> int:
    from ..study.ballots import write_plan
    from ..study.designs import make_plan

    stimuli = stimulus_names(args.stimuli)
    conditions = _recorded_motion_check(stimuli, args.stimuli, condition_names(args.conditions))
    rows = make_plan(stimuli, design=args.design, conditions=conditions, seed=args.seed, repeats=args.repeats)
    write_plan(rows, args.output)
    msg.say(f"{args.output}: {args.design} plan, {len(rows)} presentations")
    return opt.EXIT_OK


class ConditionOptionsParser(opt.Parser):
    """Reads one study condition's convert options; a mistake is a ConfigError naming the condition."""

    def error(self, message: str) -> None:  # type: ignore[override]
        from ..errors import ConfigError

        raise ConfigError(f"condition {self.prog}: {message}")


def condition_options(name: str, options: str) -> dict:
    """The settings a condition given as ``prosody convert``'s options means (a conditions file's
    ``options``); a mistake is a ConfigError naming the condition and the option."""
    import shlex

    from ..errors import ConfigError

    parser = ConditionOptionsParser(prog=name, add_help=False)
    opt.add_motion_options(parser)
    opt.add_analysis_options(parser)
    opt.add_eyebrow_options(parser)
    try:
        words = shlex.split(options)
    except ValueError as error:
        raise ConfigError(f"condition {name}: its options cannot be read ({error})") from None
    parsed = parser.parse_args(words)
    if parsed.ground_truth is not None:
        raise ConfigError(f"condition {name}: --ground-truth is found per stimulus (<stimulus>.head.csv next to "
                          "its recording); leave it out")
    try:
        opt.check_motion_options(parsed)
    except ConfigError as error:  # the library's rule, said with the condition's options
        raise ConfigError(f"condition {name}: {msg.said(error, parser)}") from None
    # what a condition is, not how many cores draw it (a manifest keeps the same recipe on another machine)
    return {key: value for key, value in opt.motion_kwargs(parsed).items() if key != "workers"}


def study_conditions(plan, path: str | None) -> dict:
    """A StudyCondition for every condition of ``plan`` (the library's :func:`prosody.study.stimuli.
    study_conditions`), conditions given as options read by this command's parser."""
    from ..study.stimuli import study_conditions as conditions_of

    return conditions_of(plan, path, read_options=condition_options)


def run_stimuli(args: argparse.Namespace) -> int:
    from ..study.designs import read_plan
    from ..study.stimuli import make_stimuli

    plan = read_plan(args.plan)
    conditions = study_conditions(plan, args.conditions)
    face = None
    if args.face is not None:
        from .preview import photo_face

        face = photo_face(args.face)
    bar = msg.ProgressBar(f"{args.output}: videos", "video")
    drawn = [0]

    def on_video(stimulus: str, condition: str, made: bool) -> None:
        drawn[0] += made

    manifest = make_stimuli(plan, args.recordings, args.output, conditions, width=args.width, force=args.force,
                            on_video=on_video, progress=bar, face=face)
    kept = len(manifest["videos"]) - drawn[0]
    msg.say(f"{args.output}: {len(manifest['videos'])} videos of {len(plan.stimuli)} stimulus/stimuli and "
            f"{len(plan.conditions)} conditions ({drawn[0]} drawn, {kept} already complete), listed in stimuli.json")
    return opt.EXIT_OK


def run_serve(args: argparse.Namespace) -> int:

    from ..net import parse_address, serve_until_interrupted
    from ..study.designs import read_plan
    from ..study.server import StudyServer
    from ..study.stimuli import check_stimuli
    from ..study.store import StudyStore

    plan = read_plan(args.plan)
    host, port = parse_address(args.listen)
    check_stimuli(plan, args.stimuli)  # before the database is made: a refused start leaves nothing behind
    new = not os.path.exists(args.db)
    store = StudyStore(args.db, plan)
    try:
        try:
            server = StudyServer(plan, args.stimuli, store, host=host, port=port, break_every=args.break_every,
                                 allow_origins=args.allow_origin,
                                 report=lambda line: msg.say(f"prosody study serve: {line}"))
        except BaseException:
            if new:
                store.close()
                for ending in ("", "-wal", "-shm"):
                    with contextlib.suppress(FileNotFoundError):
                        os.remove(args.db + ending)
            raise
        progress = store.progress()
        msg.say(f"prosody study serve: the study is at {server.url} ({plan.design}, {len(plan.trials)} trials each; "
                f"{progress['participants']} participant(s) and {progress['answers']} answer(s) so far in {args.db})")
        msg.say(f"prosody study serve: organiser's token {server.token} (export: {server.url}admin/export.csv?token="
                f"{server.token}, or 'prosody study export {args.db} -o ballots.csv')")
        if host not in ("127.0.0.1", "::1", "localhost"):
            msg.say(f"prosody study serve: warning: listening on {host}: other machines can reach the study")
        server.start()
        serve_until_interrupted(server.close)
        progress = store.progress()
        msg.say(f"prosody study serve: stopped; {progress['participants']} participant(s), {progress['finished']} "
                f"finished, {progress['answers']} answer(s) saved in {args.db}")
    finally:
        store.close()
    return opt.EXIT_OK


def run_export(args: argparse.Namespace) -> int:
    import sqlite3

    from audio_features.atomic import atomic_write

    from ..errors import ConfigError
    from ..study.store import StudyStore

    store = StudyStore(args.db, create=False)
    try:
        text = store.export_csv()
        progress = store.progress()
    except sqlite3.DatabaseError as error:
        raise ConfigError(f"{args.db}: the study database is damaged ({error})") from None
    finally:
        store.close()
    with atomic_write(args.output, newline="\n") as handle:
        handle.write(text)
    msg.say(f"{args.output}: {progress['answers']} answer(s) of {progress['participants']} participant(s) "
            f"({progress['finished']} finished), {store.design} ballots")
    return opt.EXIT_OK


def run_analyze(args: argparse.Namespace) -> int:
    from ..study.analysis import analyze_study, write_analysis

    analysis = analyze_study(args.input, args.plan)
    for note in analysis.notes:
        msg.MESSAGES.emit("warning", f"prosody study analyze: warning: {args.input}: {note}")
    write_analysis(analysis, args.output, args.report)
    msg.say(f"{args.output}: {analysis.design} study, {analysis.summary}")
    return opt.EXIT_OK


#: What ``prosody study stimuli --help`` says the command does.
STIMULI_DESCRIPTION = (
    "For every stimulus and condition of PLAN, the 3D head animated by that condition with the recording's audio, "
    "as OUT/<stimulus>/<condition>.mp4 (no curve strip and no caption, so nothing on screen names the condition), "
    "with the same frames for the ballot's WebGL head as OUT/<stimulus>/<condition>.head.json, listed in "
    "OUT/stimuli.json. Recordings are RECORDINGS/<stimulus>.wav (or another audio ending), with <stimulus>.head.csv "
    "(or .fap) for the truth condition. The thesis's four conditions need no definition; others are defined in a "
    'JSON file: {"format": "visual-prosody-study-conditions", "version": 1, "conditions": {"calm": {"label": '
    '"Calm", "options": "--activation 0.4 --pad 0.5,-0.3,0"}}}, where options are any of \'prosody convert\'\'s '
    "motion, face, expressivity and analysis options (or \"settings\": convert's keyword arguments as data, "
    "docs/studies.md). Videos already made with the same settings are kept; MP4 needs ffmpeg (or the "
    "imageio-ffmpeg package).")


def add_parser(commands) -> None:
    """Add the command to the subcommands of ``prosody``."""
    from ..study.designs import DESIGNS

    study = commands.add_parser(
        "study", help="run a perceptual study: plan it, make its videos, serve its page, export and analyse answers",
        description="A perceptual study from plan to analysis. 'plan' writes the presentation order of one of three "
                    "designs (paired comparisons as Zavala Chmelicka 2005, 1-5 opinion scores as Jia et al. 2013, "
                    "identification as Wu et al. 2006); 'stimuli' draws the face video of every stimulus and "
                    "condition; 'serve' runs the study's page and saves every answer in an SQLite database; "
                    "'export' writes the answers as ballots; 'analyze' runs the design's statistics.",
    )
    study_commands = study.add_subparsers(dest="study_command", required=True, metavar="STEP",
                                          parser_class=opt.Parser)
    plan = study_commands.add_parser(
        "plan", help="write the randomised presentation order",
        description="paired (default): every ordered pair of the conditions per stimulus (with the thesis's four, "
                    "16 pairs, same-model pairs included, so each condition is left 4 times and right 4 times), in "
                    "rounds that show one pair of every stimulus in shuffled order; CSV columns "
                    "order,stimulus,left,right. mos: every condition of every stimulus --repeats times, in rounds; "
                    "columns order,stimulus,condition. identification: the same, columns order,stimulus,shown; the "
                    "answer options are the conditions. The same seed gives the same plan; 'serve' gives each "
                    "participant their own order from it.",
    )
    plan.add_argument("--stimuli", required=True, metavar="NAME[,NAME...]|DIR",
                      help="stimulus names, comma-separated (each the name of a recording: NAME.wav), or the "
                           "folder of the recordings (every NAME.wav in it), as 'study stimuli --recordings' takes")
    plan.add_argument("--design", choices=DESIGNS, default="paired",
                      help="paired comparison (default), opinion scores 1-5, or identification")
    plan.add_argument("--conditions", default=None, metavar="NAME|FILE.json,...",
                      help="the conditions compared (default: none,random,speech,truth, the thesis's four; "
                           "identification needs its own): names, comma-separated; an item ending in .json is a "
                           "conditions file and stands for the conditions it defines (see 'study stimuli')")
    plan.add_argument("--repeats", type=opt.whole_number(1, 100, "1 to 100"), default=1, metavar="N",
                      help="mos and identification: show each condition of each stimulus N times (default 1)")
    plan.add_argument("--seed", type=opt.seed, default=0, help="seed of the order (a whole number >= 0, default 0)")
    plan.add_argument("-o", "--output", required=True, help="plan CSV to write")
    plan.set_defaults(handler=run_plan)

    stimuli = study_commands.add_parser(
        "stimuli", help="draw the video of every stimulus and condition of a plan",
        description=STIMULI_DESCRIPTION,
    )
    stimuli.add_argument("plan", metavar="PLAN.csv", help="the study's plan")
    stimuli.add_argument("--recordings", required=True, metavar="DIR", help="folder of <stimulus>.wav recordings")
    stimuli.add_argument("--conditions", default=None, metavar="FILE.json",
                         help="definitions of the plan's conditions other than the thesis's four")
    stimuli.add_argument("--width", type=opt.whole_number(64, 1920, "64 to 1920"), default=480, metavar="PX",
                         help="video width in pixels (the face is square; default 480)")
    stimuli.add_argument("--force", action="store_true", help="draw every video again")
    stimuli.add_argument("--face", default=None, metavar="PHOTO",
                         help="every video shows the head of the person in PHOTO (a JPEG or PNG of one person, "
                              "roughly frontal; the frame keeps its proportions; needs pip install "
                              "'visual-prosody[track]'); the ballot then plays the videos")
    stimuli.add_argument("-o", "--output", required=True, metavar="DIR", help="folder of the videos")
    stimuli.set_defaults(handler=run_stimuli)

    serve = study_commands.add_parser(
        "serve", help="serve the study's page to participants and save their answers",
        description="Serves a page (nothing loaded from other sites) where each participant gets an anonymous ID, "
                    "watches every trial of PLAN in their own counterbalanced order (sequence reshuffled per "
                    "participant, sides swapped for every second one), answers, gets a break every --break-every "
                    "trials, and a completion code at the end. Every answer is one SQLite transaction (WAL) in "
                    "--db: a crash, a restart or a closed tab loses nothing, a participant resumes where they "
                    "stopped (same browser, or /?participant=ID), a repeated submission counts once. Restart with "
                    "the same --db to go on. Only this server's own page may use it. Prints the organiser's token "
                    "for /admin/export.csv and /admin/progress.",
    )
    serve.add_argument("plan", metavar="PLAN.csv", help="the study's plan")
    serve.add_argument("--stimuli", required=True, metavar="DIR", help="the videos made by 'prosody study stimuli'")
    serve.add_argument("--db", required=True, metavar="study.sqlite",
                       help="the answers' database (made if missing; must be of this plan)")
    serve.add_argument("--listen", default="127.0.0.1:8766", metavar="HOST:PORT",
                       help="address to serve on (default 127.0.0.1:8766, this machine only, beside the live "
                            "page's 8765 of the docs; 0.0.0.0:PORT opens it to the network)")
    serve.add_argument("--break-every", type=opt.whole_number(0, 10000, "0 to 10000"), default=20, metavar="N",
                       help="a break screen every N trials (default 20; 0: none)")
    serve.add_argument("--allow-origin", action="append", default=[], metavar="ORIGIN",
                       help="also let pages from ORIGIN (http(s)://HOST[:PORT]) use the study (repeatable)")
    serve.set_defaults(handler=run_serve)

    export = study_commands.add_parser(
        "export", help="write the answers of a study database as ballots",
        description="Writes every answer in DB, once, as the ballots 'study analyze' reads: paired "
                    "stimulus,subject,left,right,choice; mos stimulus,subject,condition,score; identification "
                    "stimulus,subject,shown,answer; each with order (the plan's trial number). The subject is the "
                    "participant's anonymous ID. Safe while the server runs.",
    )
    export.add_argument("db", metavar="study.sqlite", help="the study's database")
    export.add_argument("-o", "--output", required=True, metavar="BALLOTS.csv", help="ballots to write")
    export.set_defaults(handler=run_export)

    analyze = study_commands.add_parser(
        "analyze", help="analyse a study's ballots (the design is read from their columns)",
        description="paired (stimulus,subject,left,right,choice): scores, and one paired t-test of per-subject "
                    "scores per pair of conditions and stimulus (a minus b, 95% CI, two-tailed p, p_holm: "
                    "Holm-corrected over the stimulus's tests). mos (stimulus,subject,condition,score): means with "
                    "95% CIs, one-way ANOVA (F, df, p, eta and omega squared), repeated-measures ANOVA over the "
                    "subjects who rated every condition (partial eta squared), Tukey's pairwise tests with Cohen's "
                    "d. identification (stimulus,subject,shown,answer): accuracy per class with exact 95% CIs and "
                    "one-sided binomial tests against chance (Holm-corrected), and the confusion matrix. Bad rows "
                    "are reported by line number. --report also writes the figure beside it.",
    )
    analyze.add_argument("input", metavar="BALLOTS.csv", help="ballot file")
    analyze.add_argument("-o", "--output", required=True, metavar="results.json", help="results to write")
    analyze.add_argument("--plan", default=None, metavar="PLAN.csv",
                         help="the study's plan: its conditions are the ones ballots may name (needed for paired "
                              "studies of conditions other than the thesis's four)")
    analyze.add_argument("--report", default=None, metavar="OUT.md",
                         help="also write a readable report, and its figure (OUT.means.png or OUT.confusion.png)")
    analyze.set_defaults(handler=run_analyze)
