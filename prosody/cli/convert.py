"""``prosody convert``: a speech recording to a FAP stream (or any format of it)."""

from __future__ import annotations

import argparse

from . import messages as msg
from . import options as opt


def run(args: argparse.Namespace) -> int:
    from ..errors import ConfigError
    from ..jobs.pipeline import convert

    opt.check_motion_options(args)
    if args.output_format is None and args.output.lower().endswith((".mp4", ".gif", ".webm", ".mov", ".mkv", ".avi")):
        raise ConfigError(f"-o {args.output!r}: convert writes motion (.fap, .csv, .json, .bvh, .livelink.csv); "
                          f"to draw a video, use 'prosody preview {args.input} -o {args.output}'")
    photo = None
    if args.face is not None:  # the photo is read, and its face found, before the audio
        from ..outputs import format_for

        if args.output == "-" or format_for(args.output, args.output_format) != "gltf":
            raise ConfigError(f"--face makes the head of the .glb output; -o {args.output!r} is not a .glb file "
                              "(to watch a photo head, use 'prosody preview --face')")
        from .preview import photo_face

        photo = photo_face(args.face)
    cues = None  # the mouth cues' own options, checked before the audio
    if args.dat_frame_rate is not None or args.extended_shapes is not None:
        from ..fap.mouth_cues import check_extended_shapes
        from ..outputs import CUE_FORMATS, format_for

        written = format_for(args.output, args.output_format) if args.output != "-" else args.output_format
        if args.dat_frame_rate is not None and written not in ("moho-dat", "prestonblair-dat"):
            raise ConfigError(f"--dat-frame-rate is the frame rate of a .dat switch file; -o {args.output!r} is not "
                              "one")
        if args.extended_shapes is not None:
            if written not in CUE_FORMATS:
                raise ConfigError(f"--extended-shapes chooses the shapes of mouth cues (.rhubarb.tsv, .rhubarb.json, "
                                  f".rhubarb.xml, .dat); -o {args.output!r} is not one")
            check_extended_shapes(args.extended_shapes)
        cues = written
    if photo is not None:
        from ..head.gltf import write_glb

        stream = convert(args.input, None, base=args.base, progress=msg.frame_progress(args.input, "analysed"),
                         **opt.motion_kwargs(args))
        write_glb(stream, args.output, photo=photo)
    elif cues is not None and args.output != "-":
        stream = _write_cues(args, args.output, cues, progress=msg.frame_progress(args.input, "analysed"))
    elif args.output == "-":
        if args.output_format is None:
            raise ConfigError("-o - writes to standard output: give --format (fap, csv, csv-physical, json, bvh, "
                              "livelink)")
        holder: list = []

        def write(path: str) -> None:
            if cues is not None:
                holder.append(_write_cues(args, path, cues))
            else:
                holder.append(convert(args.input, path, base=args.base, output_format=args.output_format,
                                      **opt.motion_kwargs(args)))

        from pathlib import Path

        msg.to_stdout(write, Path(args.input).stem + "." + args.output_format)  # the stream keeps the input's name
        stream = holder[0]
    else:
        stream = convert(args.input, args.output, base=args.base, output_format=args.output_format,
                         progress=msg.frame_progress(args.input, "analysed"), **opt.motion_kwargs(args))
    from ..outputs import format_for

    written = format_for(args.output, args.output_format)
    # a .fap file leaves out the high-level FAPs 1 (the viseme said) and 2
    faps = " ".join(str(fap) for fap in stream.active_faps if written != "fap" or fap > 2)
    if written == "bvh":
        faps = "48 49 50 (BVH holds the head only)"
    msg.say(f"{args.output}: {stream.n_frames} frames at {stream.fps:g} fps, FAPs {faps}")
    return opt.EXIT_OK


def _write_cues(args: argparse.Namespace, path: str, format_name: str, *, progress=None):
    """Convert and write mouth cues with their own options (the recording's path and length, as Rhubarb's)."""
    from audio_features.audio import open_sound_file

    from ..fap.mouth_cues import CUE_FPS
    from ..jobs.pipeline import convert
    from ..outputs import write_stream

    settings = opt.motion_kwargs(args)
    settings.setdefault("fps", CUE_FPS)  # Rhubarb's 0.01 s grid, unless --fps says otherwise
    stream = convert(args.input, None, base=args.base, progress=progress, **settings)
    with open_sound_file(args.input) as sound:
        duration_s = sound.frames / sound.samplerate if sound.frames > 0 else None
    write_stream(stream, path, format_name, sound_file=args.input, duration_s=duration_s,
                 dat_fps=args.dat_frame_rate, extended_shapes=args.extended_shapes)
    return stream


def add_parser(commands) -> None:
    """Add the command to the subcommands of ``prosody``."""
    from ..outputs import WRITERS

    convert = commands.add_parser(
        "convert", help="turn a speech recording into a FAP stream",
        description="Compute the face's motion of one condition and write it: eyebrows (FAP 31-34), head "
                    "(48-50), lips (3-11, 16-17, 51-58: visemes from the phones heard, with coarticulation, or "
                    "--lips acoustic) and, if asked, an expression or a PAD state blended onto them. "
                    "speech: brows on pitch accents, head pitch/yaw/roll from the shipped prosodic head model "
                    "(or --model arx for the thesis's ARX model, pad for the PAD gestures, or a trained file); "
                    "random: Perlin noise; none: a still head and brows; truth: recorded motion. The lips are the "
                    "same in every condition. To see the motion, draw it with 'prosody preview'.",
    )
    convert.add_argument("input", help="speech recording")
    convert.add_argument("-o", "--output", required=True,
                         help="output file; the format follows the ending: .fap (MPEG-4), .csv (FAP units), "
                              ".json, .bvh (head joint, degrees), .livelink.csv (Live Link Face style), .glb (the "
                              "3D head animated, glTF 2.0, for Blender and three.js), .rhubarb.tsv, .rhubarb.json, "
                              ".rhubarb.xml, .dat and .prestonblair.dat (the lips as Rhubarb Lip Sync's mouth "
                              "cues, for its plugins); - writes to standard output (with --format)")
    convert.add_argument("--format", dest="output_format", default=None,
                         choices=list(WRITERS),
                         help="output format, overriding the ending (csv-physical: radians and fractions of "
                              "the reference distances)")
    opt.add_motion_options(convert)
    convert.add_argument("--base", default=None, metavar="FILE.fap",
                         help="carry this recording's other FAPs (lips, eyes) into the output")
    convert.add_argument("--dat-frame-rate", type=opt.number_in(1, 1000), default=None, metavar="FPS",
                         help="with a .dat output: the switch file's frame rate, your Moho or OpenToonz project's "
                              "(default 24, as Rhubarb Lip Sync's --datFrameRate)")
    convert.add_argument("--extended-shapes", default=None, metavar="SHAPES",
                         help="with mouth cues: which of Rhubarb Lip Sync's extended shapes to use, any of G, H "
                              "and X (default GHX; '' for none: G becomes A, H C and X A, as Rhubarb's "
                              "--extendedShapes)")
    convert.add_argument("--face", default=None, metavar="PHOTO",
                         help="with a .glb output: the head of the person in PHOTO (a JPEG or PNG of one person, "
                              "roughly frontal), textured by the photo, with their hair, neck and shoulders and "
                              "the photo's background behind (needs pip install 'visual-prosody[track]')")
    opt.add_analysis_options(convert, cues=True)
    opt.add_eyebrow_options(convert)
    convert.set_defaults(handler=run)
