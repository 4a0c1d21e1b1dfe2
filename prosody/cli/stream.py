"""``prosody stream``: live audio to frames, as they become final, for files, browsers and animation tools.

The session itself is :class:`prosody.live.session.StreamSession`; this module turns the flags into its options
and its audio source, and says what happened.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

from . import messages as msg
from . import options as opt

#: How the session's checks name its options on the command line.
_FLAG_OF_FIELD = {"input": "an input", "output": "-o", "format": "--format"}


def _flag_namer(parser: argparse.ArgumentParser) -> Callable[[str], str]:
    """A field of the session's options or source -> the flag that sets it, read from the parser's dests."""
    flags = msg.flag_names(parser)

    def flag(name: str) -> str:
        return _FLAG_OF_FIELD.get(name) or flags.get(name) or f"--{name.replace('_', '-')}"

    return flag


def _source(args: argparse.Namespace):
    """The session's audio source (None: the pages' microphones only), its raw format checked here."""
    from audio_features.pcm import PcmFormat

    from ..errors import ConfigError
    from ..live.session import AudioSource

    if args.mic and args.input is not None:
        raise ConfigError("give an input or --mic, not both")
    raw = None
    if args.raw_rate is not None or args.raw_format is not None or args.raw_channels is not None:
        if args.input != "-":
            raise ConfigError("--raw-rate, --raw-format and --raw-channels describe standard input (-): a file "
                              "says its own format")
        if args.raw_rate is None:
            raise ConfigError("raw samples on standard input need --raw-rate HZ")
        raw = PcmFormat(args.raw_rate, args.raw_format or "s16le", args.raw_channels or 1)
    if args.input is None and not args.mic:
        if args.realtime:  # a page's microphone arrives at its own pace
            raise ConfigError("--realtime paces a file; standard input and microphones arrive at their own pace")
        return None
    return AudioSource(input=args.input, mic=args.mic, mic_rate=args.mic_rate, raw=raw, realtime=args.realtime)


def run(args: argparse.Namespace) -> int:
    from ..errors import ConfigError
    from ..live.session import StreamOptions, StreamSession

    source = _source(args)
    opt.check_motion_options(args)
    converter = opt.motion_kwargs(args)
    converter.pop("ground_truth")
    face = None
    if args.face is not None:  # the photo is read, and its face found, before the audio
        if args.listen is None:
            raise ConfigError("--face is the head of the page --listen serves: give --listen too")
        from .preview import photo_face

        face = photo_face(args.face)
    options = StreamOptions(output=args.output, format=args.format, listen=args.listen,
                            allow_origin=tuple(args.allow_origin), livelink=tuple(args.livelink),
                            livelink_subject=args.livelink_subject, vmc=tuple(args.vmc),
                            vmc_perfect_sync=args.vmc_perfect_sync, loop=args.loop, lookahead_ms=args.lookahead_ms,
                            converter=converter, face=face)
    session = StreamSession(options, report=lambda line: msg.say(f"prosody stream: {line}"),
                            warn=lambda line: msg.MESSAGES.emit("warning", f"prosody stream: warning: {line}"))
    result = session.run(source, flag=_flag_namer(args.parser))
    if source is None or result.passes == 0:  # served pages only, or stopped before any page came
        return opt.EXIT_OK
    to_stdout = args.output == "-"
    where = "standard output" if to_stdout else (args.output or ("the clients" if args.listen else "the links"))
    ended = "stopped by Ctrl-C or SIGTERM, the last frames flushed" if result.interrupted else "end of input"
    if args.loop:
        ended += f" after {result.passes} pass(es) of the file"
    # said once: a first sentence without a raise would otherwise look like a fault
    learning = ("; the brows rise only after the first half second of voice, which teaches them the speaker's "
                "pitch" if args.condition == "speech" and 31 in result.faps else "")
    msg.say(f"prosody stream: {where}: {result.frames} frames at {result.fps:g} fps ({ended}; look-ahead "
            f"{result.lookahead_frames / result.fps * 1000:.0f} ms{learning})")
    for sender in result.senders:
        msg.say(f"prosody stream: {sender.protocol}: {sender.sent} datagram(s) sent to "
                f"{', '.join(f'{a[0]}:{a[1]}' for _, a in sender.addresses)}"
                + (f", {sender.failed} failed" if sender.failed else ""))
    return opt.EXIT_OK


def add_parser(commands) -> None:
    """Add the command to the subcommands of ``prosody``."""
    from audio_features.pcm import RAW_FORMATS

    from ..outputs import MOTION_FORMATS

    stream = commands.add_parser(
        "stream", help="animate live audio frame by frame (a pipe, a microphone, or a file), optionally served "
                       "to browsers",
        description="Compute the prosody FAPs causally, each frame as soon as the audio up to its look-ahead has "
                    "arrived: frame k (at k/fps s) uses the audio up to k/fps + the look-ahead and nothing later, "
                    "and is given out about the look-ahead plus 35 ms after its audio (plus the time the audio "
                    "takes to reach the command). The brows (accent rule by default) and the head (a live form of "
                    "the default head model, trained for that look-ahead) are those of 'convert' computed without "
                    "the future: the speaker's median pitch and level are learnt as the stream goes, so the first "
                    "second or so of voice moves little. Ends at the end of the input or on Ctrl-C, the last "
                    "frames flushed.",
    )
    stream.add_argument("input", nargs="?", default=None,
                        help="audio file, or - for standard input: a WAV stream (its header may not know the "
                             "length) or raw samples with --raw-rate")
    stream.add_argument("-o", "--output", default=None,
                        help="- writes one JSON line per frame to standard output as each frame is ready: "
                             '{"frame": k, "time_s": t, "faps": {"31": v, ..., "50": v}} (FAP units; channels that '
                             "are off are absent); a file (.fap, .csv, .json, .bvh, .livelink.csv, .jsonl) is "
                             "written when the stream ends")
    stream.add_argument("--format", default=None,
                        choices=MOTION_FORMATS,
                        help="format of the output file, overriding its ending")
    stream.add_argument("--lookahead-ms", type=opt.lookahead, default=100.0, metavar="MS",
                        help="audio after each frame that the frame may use, in ms (default 100: the most that "
                             "keeps the median delay near 150 ms; more makes the head follow the speech better, "
                             "0 gives the least delay; rounded to whole frames)")
    source = stream.add_argument_group("input")
    source.add_argument("--mic", action="store_true",
                        help="read the default microphone (needs the sounddevice package: "
                             "pip install 'visual-prosody[mic]')")
    source.add_argument("--mic-rate", type=opt.sample_rate, default=16000, metavar="HZ",
                        help="sample rate asked of the microphone (default 16000)")
    source.add_argument("--loop", action="store_true",
                        help="play the file again and again at its own pace until Ctrl-C (a demo for --listen, "
                             "--livelink or --vmc); with --listen it starts when the first page connects")
    source.add_argument("--realtime", action="store_true",
                        help="read a file no faster than it plays (a demo of live input)")
    source.add_argument("--raw-rate", type=opt.sample_rate, default=None, metavar="HZ",
                        help="standard input holds raw samples at HZ instead of a WAV stream")
    source.add_argument("--raw-format", default=None, choices=list(RAW_FORMATS),
                        help="sample format of raw input (default s16le: 16-bit signed little-endian)")
    source.add_argument("--raw-channels", type=opt.whole_number(1, 64, "1 to 64"), default=None, metavar="N",
                        help="interleaved channels of raw input, mixed to mono (default 1)")
    stream.add_argument("--listen", default=None, metavar="HOST:PORT",
                        help="also serve the frames over a WebSocket, and at http://HOST:PORT/ a page that draws "
                             "the face moving with them and can send the browser's microphone (127.0.0.1 when "
                             "HOST is left out; another address lets anyone who can reach it watch the stream and "
                             "send audio to this machine); port 0 picks a free one")
    stream.add_argument("--face", default=None, metavar="PHOTO",
                        help="with --listen: the page shows the head of the person in PHOTO (a JPEG or PNG of one "
                             "person, roughly frontal; needs pip install 'visual-prosody[track]')")
    stream.add_argument("--allow-origin", action="append", default=[], metavar="ORIGIN",
                        help="with --listen: also let pages from ORIGIN (http(s)://HOST[:PORT]) open the stream; "
                             "by default only the page served at --listen's own address may (repeatable)")
    links = stream.add_argument_group(
        "sending to animation tools", "each frame of the input is sent over UDP as soon as it is ready; a tool "
        "that is not listening loses those frames (said once)")
    links.add_argument("--livelink", action="append", default=[], metavar="HOST[:PORT]",
                       help="send Live Link Face packets, as the iPhone app does, to Unreal's Live Link at "
                            "HOST (port 11111 unless given; repeatable): 52 ARKit blendshapes and the head's "
                            "yaw, pitch and roll in radians")
    links.add_argument("--livelink-subject", default="prosody", metavar="NAME",
                       help="the subject name Unreal lists the stream under (default prosody)")
    links.add_argument("--vmc", action="append", default=[], metavar="HOST[:PORT]",
                       help="send the VMC protocol (OSC) to a marionette such as VSeeFace, VMagicMirror or "
                            "Warudo at HOST (port 39539 unless given; repeatable): the Head bone's rotation and "
                            "VRM's A I U E O and blink presets")
    links.add_argument("--vmc-perfect-sync", action="store_true",
                       help="send the 52 ARKit blendshapes of 'perfect sync' avatars instead of VRM's presets "
                            "(VRM's presets have no brows: this is how the brows reach such an avatar)")
    opt.add_motion_options(stream, live=True)
    opt.add_analysis_options(stream)
    opt.add_eyebrow_options(stream)
    stream.set_defaults(handler=run)
