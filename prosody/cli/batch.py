"""``prosody batch``: compare every recording of a folder, resumable, with a summary."""

from __future__ import annotations

import argparse
import dataclasses
import warnings

from . import messages as msg
from . import options as opt


def run(args: argparse.Namespace) -> int:
    from ..jobs.batch import BatchOptions, find_audio_files, run_batch
    from ..motion.expressivity import Expressivity

    conditions = [name for value in args.condition for name in value.split(",") if name.strip()] or None
    if args.brow_semitones is not None:  # the old name, kept working for a while
        from ..errors import ConfigError

        semitones = "accent_semitones" if args.brows == "accent" else "eyebrow_semitones"
        if getattr(args, semitones) is not None:
            raise ConfigError(f"--brow-semitones is the old name of --{semitones.replace('_', '-')}: give one")
        setattr(args, semitones, args.brow_semitones)
        warnings.warn(f"--brow-semitones is now --{semitones.replace('_', '-')}, as in the other commands",
                      FutureWarning, stacklevel=1)
    if args.language is not None and not args.transcripts:
        from ..errors import ConfigError

        raise ConfigError("--language is the transcripts' language: add --transcripts (<stem>.txt beside each "
                          "recording)")
    options = BatchOptions(model=args.model, seed=args.seed, seeds=args.seeds, normalize=args.normalize,
                           plots=args.plots, video=args.video, brows=args.brows, eyebrow_rule=opt.eyebrow_rule(args),
                           lips=None if args.lips == "none" else args.lips,
                           expressivity=(opt.expressivity(args) or Expressivity()).as_dict(),
                           expression=args.expression, transcripts=args.transcripts, language=args.language,
                           **opt.channel_kwargs(args), **opt.analysis_kwargs(args, parallel=False))
    if conditions:
        options = dataclasses.replace(options, conditions=tuple(conditions))
    on_outcome = msg.outcome_reporter(args.parser, args.output, "file", len(find_audio_files(args.input)),
                                   lambda outcome: outcome.file)

    summary = run_batch(args.input, args.output, ground_truth_dir=args.ground_truth_dir, options=options,
                        jobs=args.jobs, scheduler=args.scheduler, force=args.force, on_outcome=on_outcome)
    counts = summary["counts"]
    msg.say(f"{args.output}: {counts['files']} file(s), {counts['done']} processed, {counts['skipped']} already "
            f"complete, {counts['failed']} failed; summary in summary.md and summary.json")
    return opt.EXIT_FAILURE if counts["failed"] else opt.EXIT_OK


def add_parser(commands) -> None:
    """Add the command to the subcommands of ``prosody``."""
    from ..motion.face.lips import LIP_METHODS

    batch = commands.add_parser(
        "batch", help="convert and compare every audio file of a folder tree",
        description="Process every audio file under INDIR (recursively) into OUTDIR/<relative folder>/<stem>/ "
                    "(condition .fap files and metrics.json; figures and report with --plots), comparing with "
                    "ground truth where <stem>.head.csv or <stem>.fap is found in --ground-truth-dir (same "
                    "relative path, or its top). Writes OUTDIR/summary.md and summary.json. A broken file is "
                    "reported and skipped; the exit code is 1 if any failed. Re-running skips complete outputs "
                    "made with the same settings.",
    )
    batch.add_argument("input", metavar="INDIR", help="folder of recordings")
    batch.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output folder (created)")
    batch.add_argument("--ground-truth-dir", default=None, metavar="DIR", help="folder of recorded motion")
    batch.add_argument("--condition", action="append", default=[], metavar="NAME[,NAME]",
                       help="conditions to produce: none, random, speech, truth (repeatable; default all, truth "
                            "only where found)")
    batch.add_argument("--jobs", type=int, default=1, help="local worker processes (default 1)")
    batch.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="run on a Dask distributed cluster, e.g. tcp://host:8786 (needs the 'cluster' extra)")
    opt.add_generator_options(batch)
    opt.add_seeds_option(batch)
    batch.add_argument("--lips", default="visemes", choices=[*LIP_METHODS, "none"],
                       help="how the lips move, alike in every condition (default visemes; see convert --help); "
                            "with a <clip>.mouth.csv beside the ground truth, the lips are measured against it")
    batch.add_argument("--brow-semitones", type=opt.number_in(0, 24, low_open=True), default=None,
                       help=argparse.SUPPRESS)  # the old name of --accent-semitones (--eyebrow-semitones)
    batch.add_argument("--expression", default=None, metavar="NAME[:INTENSITY]",
                       help="a facial expression over every recording, as convert --expression (a name of "
                            "'convert --help', intensity 0-1)")
    batch.add_argument("--transcripts", action="store_true",
                       help="read <stem>.txt beside each recording, where there is one, as what it says (as "
                            "convert --transcript; with --lips visemes or combined)")
    batch.add_argument("--language", default=None, metavar="CODE",
                       help="with --transcripts: their language, an eSpeak NG code, as convert --language")
    batch.add_argument("--normalize", action="store_true", help="normalise as 'prosody compare --normalize'")
    batch.add_argument("--plots", action=argparse.BooleanOptionalAction, default=False,
                       help="also write figures and a report per file (default --no-plots, for speed)")
    batch.add_argument("--video", action="store_true",
                       help="also write each file's conditions.mp4, as compare --video (needs ffmpeg or the "
                            "imageio-ffmpeg package)")
    batch.add_argument("--force", action="store_true", help="redo files whose outputs are already complete")
    opt.add_channel_options(batch)
    opt.add_expressivity_options(batch)
    opt.add_analysis_options(batch)
    opt.add_eyebrow_options(batch)
    batch.set_defaults(handler=run)
