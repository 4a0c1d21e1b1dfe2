"""``prosody track``: head, brow and mouth motion tracked from videos."""

from __future__ import annotations

import argparse

from . import messages as msg
from . import options as opt


def run(args: argparse.Namespace) -> int:
    from ..jobs.track import TrackOptions, find_videos, track_videos

    options = TrackOptions(av_offset_ms=args.av_offset_ms, max_gap_s=args.max_gap,
                           max_side_px=None if args.max_side == 0 else args.max_side)
    from ..tracking.curves import SyncEstimate

    def result(outcome) -> str | None:
        if outcome.sync is None:
            return None
        sync = SyncEstimate(**{key: outcome.sync.get(key) for key in ("lead_ms", "r", "spread_ms", "reason")})
        # the parenthesis is the clip's length, as every command's; the time taken follows it
        took = "already complete" if outcome.status == "skipped" else f"tracked in {outcome.seconds:.1f} s"
        return (f"{outcome.stem}: {outcome.frames} frames at 30 fps ({outcome.frames / 30:.1f} s), {took}; "
                f"{sync.describe()}")

    on_outcome = msg.outcome_reporter(args.parser, args.output, "video", len(find_videos(args.input)),
                                   lambda outcome: outcome.video, result)

    outcomes = track_videos(args.input, args.output, options=options, audio=args.audio, jobs=args.jobs,
                            scheduler=args.scheduler, force=args.force, on_outcome=on_outcome)
    failed = sum(outcome.status == "failed" for outcome in outcomes)
    skipped = sum(outcome.status == "skipped" for outcome in outcomes)
    msg.say(f"{args.output}: {len(outcomes)} video(s), {len(outcomes) - failed - skipped} tracked, {skipped} already "
            f"complete, {failed} failed")
    return opt.EXIT_FAILURE if failed else opt.EXIT_OK


def add_parser(commands) -> None:
    """Add the command to the subcommands of ``prosody``."""
    track = commands.add_parser(
        "track", help="track talking-head videos into head, brow and mouth curves (the files train and compare "
                      "read)",
        description="Run a face tracker (MediaPipe FaceLandmarker) on each video and write, into OUTDIR, "
                    "<stem>.wav (its sound, 16 kHz mono), <stem>.head.csv, <stem>.brows.csv and <stem>.mouth.csv "
                    "(30 fps, frame k at k/30 s of the sound; empty cells where the face is not found) and "
                    "<stem>.track.json (what was done, how the mouth's motion lines up with the sound, and how far "
                    "the tracked mouth can be trusted: mouth_agreement). "
                    "Folders are searched for videos recursively. With several faces in view, the largest one of "
                    "the first frame is followed. A video without sound takes the WAV of the same name beside it. "
                    "Complete outputs are skipped on a re-run. Needs: pip install 'visual-prosody[track]'.",
    )
    track.add_argument("input", nargs="+", metavar="VIDEO", help="video files or folders of them")
    track.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output folder (created)")
    track.add_argument("--audio", default=None, metavar="FILE",
                       help="the sound of a single video that has none (default: <stem>.wav beside it, if any)")
    track.add_argument("--av-offset-ms", type=opt.number_in(-5000, 5000), default=0.0, metavar="MS",
                       help="move the motion this many ms later against the sound (negative: earlier), for a "
                            "video whose picture runs ahead of its sound (default 0; track.json gives an estimate)")
    track.add_argument("--max-gap", type=opt.number_in(0, 10), default=0.25, metavar="S",
                       help="bridge stretches without the face up to S seconds by interpolation; longer ones stay "
                            "empty (default 0.25)")
    track.add_argument("--max-side", type=opt.whole_number(0, 8192, "0 to 8192"), default=1280, metavar="PX",
                       help="scale frames larger than PX down before tracking (default 1280; 0 keeps them)")
    track.add_argument("--jobs", type=int, default=1, help="local worker processes (default 1)")
    track.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="run on a Dask distributed cluster (scheduler address), as batch")
    track.add_argument("--force", action="store_true", help="redo videos whose outputs are already complete")
    track.set_defaults(handler=run)
