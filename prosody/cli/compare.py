"""``prosody compare``: the four conditions of one recording, measured side by side."""

from __future__ import annotations

import argparse
from typing import Any

from . import messages as msg
from . import options as opt


def run(args: argparse.Namespace) -> int:
    from ..errors import ConfigError
    from ..evaluation.compare import compare, write_comparison
    from ..motion.settings import FaceSettings

    # the face's rules are the library's (said with the flags), checked before the photo and the audio
    FaceSettings(lips=None if args.lips == "none" else args.lips, transcript=args.transcript, language=args.language,
                 mouth_model=args.mouth_model, pad=args.pad, pad_map=args.pad_map)
    face: Any = "head"
    if args.face is not None:  # the photo is read, and its face found, before the audio
        if not args.video:
            raise ConfigError("--face is the face of the video: give --video too")
        from .preview import photo_face

        face = photo_face(args.face)
    comparison = compare(args.input, ground_truth=args.ground_truth, model=args.model, seed=args.seed,
                         seeds=args.seeds, normalize=args.normalize, eyebrow_rule=opt.eyebrow_rule(args),
                         other_head_models={name: name for name in args.also_model},
                         lips=None if args.lips == "none" else args.lips, transcript=args.transcript,
                         language=args.language,
                         expression=args.expression, mouth=args.mouth, mouth_model=args.mouth_model,
                         expressivity=opt.expressivity(args), pad=args.pad, pad_map=args.pad_map,
                         **opt.channel_kwargs(args), **opt.analysis_kwargs(args))
    written = write_comparison(comparison, args.output, plots=args.plots, video=args.video,
                               exaggerate=args.exaggerate, face=face,
                               progress=msg.frame_progress(f"{args.output}/conditions.mp4") if args.video else None)
    line = f"{args.output}: {len(written)} files"
    head = comparison.metrics["conditions"]["SPEECH_DRIVEN"]["head"]
    control = comparison.metrics["controls"]["mismatched_audio"]
    if head["speed_envelope_r"] is not None:
        line += (f"; SPEECH_DRIVEN speed-envelope r {head['speed_envelope_r']:+.2f} "
                 f"(mismatched audio {control['speed_envelope_r'] or 0:+.2f}), pitch r {head['pitch_r'] or 0:+.2f} "
                 f"(mismatched audio {control['pitch_r'] or 0:+.2f})")
    msg.say(line)
    return opt.EXIT_OK


def add_parser(commands) -> None:
    """Add the command to the subcommands of ``prosody``."""
    compare = commands.add_parser(
        "compare", help="compare the four conditions on one recording (FAP files, plots, report, metrics)",
        description="Write OUTDIR/no_prosody.fap, random.fap, speech_driven.fap (and ground_truth.fap with "
                    "--ground-truth), features.png and head.png, report.md and metrics.json. With recorded motion, "
                    "the report leads with the head measures of each condition: speed-envelope r (does the head "
                    "move when the recording moves), pitch r, the spread of each axis as a ratio to the "
                    "recording's, and the velocity-spectrum distance (too still or too jittery), beside the "
                    "speech-driven generator driven by this recording's audio shifted in time (a control that "
                    "keeps the audio's statistics but not its timing); then the brows against recorded brows "
                    "(<clip>.brows.csv beside the .head.csv), statistics per FAP, Pearson r and RMSE, and "
                    "canonical correlations. Random and speech-driven measures are averaged over --seeds seeds.",
    )
    compare.add_argument("input", help="speech recording")
    compare.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output folder (created)")
    compare.add_argument("--ground-truth", default=None, metavar="FILE",
                         help="recorded motion: <clip>.head.csv or .fap (enables GROUND_TRUTH and agreement)")
    opt.add_generator_options(compare)
    opt.add_seeds_option(compare)
    compare.add_argument("--also-model", action="append", default=[], metavar="NAME|FILE",
                         help="measure another head model beside the speech-driven one, with its own control "
                              "(e.g. --also-model arx: the thesis's model next to the default; repeatable); its "
                              "speech-driven stream is written as speech_driven.<NAME>.fap and gets a panel in "
                              "--video")
    compare.add_argument("--normalize", action="store_true",
                         help="scale and offset RANDOM, SPEECH_DRIVEN and GROUND_TRUTH to the same mean and "
                              "standard deviation per FAP (the ground truth's where it has the FAP), as the "
                              "thesis's second experiment did")
    compare.add_argument("--plots", action=argparse.BooleanOptionalAction, default=True,
                         help="write the PNG figures (default; --no-plots skips them), as batch --plots")
    compare.add_argument("--video", action="store_true",
                         help="also write OUTDIR/conditions.mp4: the conditions' faces side by side, labelled, "
                              "with the recording's audio (needs ffmpeg or the imageio-ffmpeg package)")
    compare.add_argument("--mouth", default=None, metavar="FILE.mouth.csv",
                         help="a video-tracked mouth for the lip measures (default: the <clip>.mouth.csv beside "
                              "the ground truth or the audio, if any)")
    opt.add_face_options(compare)
    opt.add_channel_options(compare)
    opt.add_expressivity_options(compare)
    compare.add_argument("--exaggerate", type=opt.exaggeration, default=1.0, metavar="X",
                         help="with --video: draw head angles and brow raises X times larger (default 1)")
    compare.add_argument("--face", default=None, metavar="PHOTO",
                         help="with --video: every panel is the head of the person in PHOTO (a JPEG or PNG of one "
                              "person, roughly frontal; needs pip install 'visual-prosody[track]')")
    opt.add_analysis_options(compare)
    opt.add_eyebrow_options(compare)
    compare.set_defaults(handler=run)
