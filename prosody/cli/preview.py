"""``prosody preview``: the motion played on the 3D head (or the drawn face), as MP4 or GIF."""

from __future__ import annotations

import argparse

from . import messages as msg
from . import options as opt


def say_unshown(stream, face: str, source: str) -> None:
    """One line naming the FAPs of ``stream`` that ``face`` does not show (none: nothing said)."""
    import numpy as np

    present = [int(f) + 1 for f in np.flatnonzero(stream.mask.any(axis=0))]
    if 3 in present:  # a viseme (FAP 1) that came with low-level lips is shown by them
        present = [f for f in present if f != 1]
    if face == "head":
        from ..head.rig import head_rig

        missing = head_rig().unsupported(present)
    else:
        from ..evaluation.preview import DRAWN_FAPS

        missing = [f for f in present if f not in DRAWN_FAPS]
    if missing:
        shown = "3D head" if face == "head" else "drawn face"
        msg.say(f"{source}: the {shown} does not show FAP {fap_ranges(missing)} (in the stream; left out)")


def check_sound_file(path: str) -> None:
    """``--audio`` is a regular file: a FIFO would hang ffmpeg, a device (``/dev/zero``) never end."""
    import os
    import stat
    from pathlib import Path

    from ..errors import ConfigError

    try:
        mode = os.stat(path).st_mode
    except OSError as error:
        raise ConfigError(f"--audio {path}: {error.strerror or error}") from None
    if not stat.S_ISREG(mode):
        kind = "a directory" if stat.S_ISDIR(mode) else "a pipe or a device"
        raise ConfigError(f"--audio {Path(path)}: {kind}, not a sound file (the video's sound is read whole; "
                          "save it to a file first)")


def face_choice(text: str) -> str:
    """``--face``: head, drawn, or the path of a JPEG or PNG photo."""
    from pathlib import Path

    from ..evaluation.preview import FACES, PHOTO_ENDINGS

    if text in FACES or Path(text).suffix.lower() in PHOTO_ENDINGS:
        return text
    raise argparse.ArgumentTypeError(f"{', '.join(FACES)} or a photo ({', '.join(PHOTO_ENDINGS)}), not {text!r}")


def preview_face(face: str):
    """The face a preview shows: a name, or the head made from the photo (its notes said once)."""
    from ..evaluation.preview import FACES

    return face if face in FACES else photo_face(face)


def photo_face(path: str):
    """The head of the person in the photo at ``path``, its notes said once."""
    from ..head.photo import photo_head

    head = photo_head(path)
    for note in head.notes:
        msg.say(f"{path}: {note}")
    return head


def fap_ranges(faps: list[int]) -> str:
    """[1, 2, 3, 5] -> '1-3, 5'."""
    runs: list[list[int]] = []
    for fap in sorted(faps):
        if runs and fap == runs[-1][-1] + 1:
            runs[-1].append(fap)
        else:
            runs.append([fap])
    return ", ".join(f"{run[0]}-{run[-1]}" if len(run) > 2 else ", ".join(map(str, run)) for run in runs)


def strip_scales(text: str | None) -> tuple[float, float] | None:
    """``--strip-scale BROW_ENS,HEAD_DEG`` as (ENS, AU), each a number of 0.001 to a million."""
    if text is None:
        return None
    from ..errors import ConfigError
    from ..fap.units import AU_PER_DEGREE

    try:
        brow_ens, head_deg = (float(part) for part in text.split(","))
    except ValueError:
        raise ConfigError(f"--strip-scale takes BROW_ENS,HEAD_DEG (e.g. 30,10), got {text!r}") from None
    if not all(0.001 <= value <= 1e6 for value in (brow_ens, head_deg)):
        raise ConfigError(f"--strip-scale takes two numbers of 0.001 to 1000000 (ENS, degrees), got {text!r}")
    return brow_ens, head_deg * AU_PER_DEGREE


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ..evaluation.preview import write_preview

    opt.check_motion_options(args)
    if args.audio is not None and not args.no_audio:
        check_sound_file(args.audio)
    from ..fap.exporters import is_stream_file, read_stream

    if is_stream_file(args.input):
        given = opt.making_options_given(args)
        if given:
            from ..errors import ConfigError

            verb = "makes" if len(given) == 1 else "make"
            raise ConfigError(f"{args.input} is a stream, shown as it is: {', '.join(given)} {verb} a stream from a "
                              f"recording (use {'it' if len(given) == 1 else 'them'} with 'prosody preview "
                              "RECORDING', or 'prosody convert' first)")
    scales = strip_scales(args.strip_scale)
    face = preview_face(args.face)  # a photo is read, and its face found, before the audio
    audio = args.audio
    if is_stream_file(args.input):
        stream = read_stream(args.input)
    elif Path(args.input).suffix.lower() == ".csv":
        from ..errors import ConfigError

        raise ConfigError(f"{args.input}: preview draws a recording or a .fap, .json or .jsonl stream; a .csv "
                          "export is not read back (convert to .json to preview the stream)")
    else:
        from ..jobs.pipeline import convert

        stream = convert(args.input, None, **opt.motion_kwargs(args))
        audio = audio or args.input
    if args.no_audio:
        audio = None
    say_unshown(stream, "drawn" if args.face == "drawn" else "head", args.input)
    write_preview(stream, args.output, audio=audio, width=args.width, exaggerate=args.exaggerate,
                  brow_scale=args.brow_scale, start_s=args.start_s, duration_s=args.duration_s,
                  progress=msg.frame_progress(args.output), scales=scales, face=face, strip=not args.no_strip)
    sound = " with sound" if audio is not None and Path(args.output).suffix.lower() == ".mp4" else ""
    from ..evaluation.preview import excerpt_frames

    first, count = excerpt_frames(stream.n_frames, stream.fps, args.start_s, args.duration_s)
    frames = f"{count} frame{'s' if count != 1 else ''}, {count / stream.fps:.2f} s"
    excerpt = (f"{frames} from {first / stream.fps:.2f} s" if args.start_s or args.duration_s is not None
               else frames)
    msg.say(f"{args.output}: preview of {stream.name} ({excerpt}){sound}")
    return opt.EXIT_OK


def add_parser(commands) -> None:
    """Add the command to the subcommands of ``prosody``."""
    preview = commands.add_parser(
        "preview", help="play the motion on a 3D head, as an MP4 (with the audio) or a GIF",
        description="Animate a 3D head from one condition's stream (as 'prosody convert' makes it), from any "
                    ".fap file (Greta's, Xface's, SEMAINE's: the FAPs the head has no part for are named once), "
                    "or from this package's .json or stream .jsonl output: the head turns about the neck (FAP "
                    "48-50), the jaw, lips, lids, eyeballs, brows, cheeks, nose and tongue move by their FAPs "
                    "(3-46, 51-64) in MPEG-4's units measured on the head, at true scale unless --exaggerate or "
                    "--brow-scale; a strip below plots the brow and "
                    "head curves around the current frame. --face PHOTO shows the head of the person in a JPEG or "
                    "PNG, in the photo's framing; --face drawn shows the older drawn face (head, brows, "
                    "lips, lids), a diagnostic. .mp4 (H.264, with the recording's audio) needs ffmpeg on PATH or "
                    "the imageio-ffmpeg package; .gif (no sound, at most 1 minute at 30 fps) always works.",
    )
    preview.add_argument("input", help="speech recording, or a .fap, .json or .jsonl stream to show as it is")
    preview.add_argument("-o", "--output", required=True, metavar="OUT.mp4|OUT.gif", help="video to write")
    preview.add_argument("--audio", default=None, metavar="FILE",
                         help="sound for the MP4 when INPUT is a .fap file (default: INPUT itself if audio)")
    preview.add_argument("--no-audio", action="store_true", help="write the MP4 without sound")
    preview.add_argument("--width", type=int, default=None, metavar="PX",
                         help="frame width in pixels (default 480, the height 5/4 of it; with a photo, the "
                              "photo's own width and proportions)")
    preview.add_argument("--exaggerate", type=opt.exaggeration, default=1.0, metavar="X",
                         help="draw head angles and brow raises X times larger (default 1: true scale)")
    preview.add_argument("--brow-scale", type=opt.exaggeration, default=1.0, metavar="X",
                         help="draw the brow raises X times larger again (default 1: true size, as every other "
                              "FAP; another value is said on every frame)")
    preview.add_argument("--face", type=face_choice, default="head", metavar="head|drawn|PHOTO",
                         help="the 3D head (default), the drawn diagnostic face, or PHOTO (a JPEG or PNG of one "
                              "person, roughly frontal, lips closed animates best): that person's head, the face "
                              "fitted to the photo's landmarks and textured by it, hair, neck and background "
                              "from the photo (needs pip install 'visual-prosody[track]')")
    preview.add_argument("--no-strip", action="store_true", help="the face alone, without the curve strip")
    preview.add_argument("--start", dest="start_s", type=opt.seconds, default=0.0, metavar="S",
                         help="first second shown (default 0)")
    preview.add_argument("--strip-scale", default=None, metavar="BROW_ENS,HEAD_DEG",
                         help="full scale of the curve strip: brow raise in ENS and head angle in degrees (default: "
                              "this stream's largest values); give previews you compare the same scale, e.g. 30,10")
    preview.add_argument("--duration", dest="duration_s", type=opt.number_in(0, 1e6, low_open=True), default=None,
                         metavar="S",
                         help="seconds shown (default: to the end)")
    opt.add_motion_options(preview)
    opt.add_analysis_options(preview)
    opt.add_eyebrow_options(preview)
    preview.set_defaults(handler=run)
