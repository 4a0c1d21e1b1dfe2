"""``prosody train``: fit a head, live head or mouth model on paired recordings."""

from __future__ import annotations

import argparse

from audio_features.defaults import DEFAULT_FPS

from . import messages as msg
from . import options as opt


def run(args: argparse.Namespace) -> int:
    from ..errors import ConfigError
    from ..motion.heads.training import train

    orders = {"na": args.na, "nb": args.nb, "nk": args.nk, "ridge": args.ridge}
    if args.kind == "live" and len(args.data) > 1:
        raise ConfigError(f"--kind {args.kind} trains on one folder; give --data once")
    if args.lookahead_ms is not None and args.kind != "live":
        raise ConfigError("--lookahead-ms sets the live head model's look-ahead: add --kind live")
    if args.kind == "mouth":
        from ..motion.face.mouth_model import train_mouth

        given = [f"--{name}" for name, value in orders.items() if value is not None] + (["--cv"] if args.cv else [])
        if given:
            raise ConfigError(f"{', '.join(given)} do(es) not apply to the mouth model (its held-out figures come "
                              "from experiments/mouth_loco.py and experiments/mouth_videos_loso.py)")
        train_mouth(args.data, args.output, fps=args.fps, report=msg.say)
        return opt.EXIT_OK
    if args.kind == "live":
        from ..motion.heads.live_training import train_live

        given = [f"--{name}" for name, value in orders.items() if value is not None]
        if given:
            raise ConfigError(f"{', '.join(given)} set(s) the ARX model's orders: add --kind arx")
        given_lookahead = {} if args.lookahead_ms is None else {"lookahead_ms": args.lookahead_ms}
        train_live(args.data[0], args.output, cv=args.cv, fps=args.fps, report=msg.say, **given_lookahead)
        return opt.EXIT_OK
    if args.kind != "arx":
        given = [f"--{name}" for name, value in orders.items() if value is not None]
        if given:
            raise ConfigError(f"{', '.join(given)} set(s) the ARX model's orders: add --kind arx")
    from ..motion.heads.arx import ARX_DEFAULTS

    orders = {name: ARX_DEFAULTS[name] if value is None else value for name, value in orders.items()}
    train(args.data, args.output, kind=args.kind, cv=args.cv, fps=args.fps,
          report=msg.say, **orders)
    return opt.EXIT_OK


def add_parser(commands) -> None:
    """Add the command to the subcommands of ``prosody``."""
    from ..motion.heads.training import MODEL_KINDS

    train = commands.add_parser(
        "train", help="train a head-motion model on paired recordings",
        description="Fit a head model on every <name>.wav in DIR that has a <name>.head.csv (columns "
                    "frame,time_s,rx_rad,ry_rad,rz_rad at 30 fps) or a <name>.fap beside it. A pair whose "
                    "durations differ by more than two frames is reported and skipped. --kind prosodic (the "
                    "default) learns how much the head moves and how it nods from the speech, and the size and "
                    "tempo of the recorded motion; --kind arx fits the thesis's linear ARX model; --kind live fits "
                    "the causal form of the prosodic model for 'prosody stream'. Use the file with --model in "
                    "convert, compare, batch and preview (live models: in stream).",
    )
    train.add_argument("--data", required=True, action="append", metavar="DIR",
                       help="folder of paired recordings (<name>.wav with <name>.head.csv or .fap, as 'prosody "
                            "track' writes them); repeat it to train on several. A speakers.csv (columns "
                            "recording,speaker) in a folder makes --cv hold out a speaker's recordings together")
    train.add_argument("-o", "--output", required=True, help="model file to write (.json)")
    train.add_argument("--kind", default="prosodic", choices=[*MODEL_KINDS, "live", "mouth"],
                       help="which model to fit (default prosodic; pad: Jia et al.'s gestures with Eq. 2's arousal "
                            "coefficients fitted to the recordings' amplitude per prosodic word, for --model FILE; "
                            "live: the causal form of the prosodic model "
                            "that 'prosody stream' uses, trained on the audio analysed as a stream; mouth: the "
                            "acoustic mouth model of --lips acoustic, on <name>.wav + <name>.mouth.csv pairs)")
    train.add_argument("--lookahead-ms", type=opt.lookahead, default=None, metavar="MS",
                       help="--kind live: audio after each frame the model reads, in ms (default 100); stream "
                            "with at least this --lookahead-ms")
    train.add_argument("--cv", action="store_true",
                       help="leave-one-speaker-out cross-validation (a folder's speakers.csv names the speakers; "
                            "without one, each recording is its own): for prosodic, choose its settings by the "
                            "held-out speed-envelope and pitch correlations above the mismatched-audio control "
                            "and store those figures in the model file (pitch share, speed passes, envelope power, "
                            "pitch follow); for live, its presence window or pitch follow the same way; for arx, "
                            "choose na, nb, nk and the ridge penalty by free-run error (the head measures are "
                            "reported beside it)")
    arx = train.add_argument_group("ARX orders (--kind arx only)")
    arx.add_argument("--na", type=int, default=None, help="past outputs fed back (default 1)")
    arx.add_argument("--nb", type=int, default=None, help="input lags (default 5)")
    arx.add_argument("--nk", type=int, default=None, help="input delay in frames (default 0)")
    arx.add_argument("--ridge", type=opt.number_in(0, 1e6), default=None, metavar="R",
                     help="ridge penalty, 0 to 1e6 (default 0.1)")
    train.add_argument("--fps", type=opt.number_in(1, 1000), default=DEFAULT_FPS,
                       help=f"frame rate (default {DEFAULT_FPS:g}, 1 to 1000)")
    train.set_defaults(handler=run)
