"""`prosody stream --livelink / --vmc` against receivers written here from the protocols' published
descriptions (Unreal's Live Link Face packet, OSC 1.0 and the VMC protocol's marionette messages), on loopback."""

from __future__ import annotations

import json
import math
import socket
import struct
import subprocess
import sys
import threading

import numpy as np
import pytest
from conftest import REPO
from scipy.spatial.transform import Rotation

from prosody.cli import main
from prosody.fap.exporters import BROW_FULL_SCALE_ENS, LIVELINK_FULL_SCALE
from prosody.fap.live_links import LIVELINK_PACKET_BLENDSHAPES, livelink_packet, unity_head_rotation
from prosody.fap.table import RADIANS_PER_AU

SAMPLE = REPO / "samples" / "arctic_a0009.wav"


class _Receiver(threading.Thread):
    """A UDP socket on loopback keeping every datagram until none comes for a while."""

    def __init__(self, family: int = socket.AF_INET, host: str = "127.0.0.1") -> None:
        super().__init__(daemon=True)
        self.socket = socket.socket(family, socket.SOCK_DGRAM)
        self.socket.bind((host, 0))
        self.socket.settimeout(20)
        self.port = self.socket.getsockname()[1]
        self.datagrams: list[bytes] = []

    def run(self) -> None:
        try:
            while True:
                self.datagrams.append(self.socket.recv(65536))
                self.socket.settimeout(2)
        except OSError:
            pass
        finally:
            self.socket.close()


# Live Link Face, as Unreal's receiver reads it -------------------------------------------------------------
#: Unreal's EARFaceBlendShape, the order of a packet's 61 values.
UNREAL_CURVES = """
    EyeBlinkLeft EyeLookDownLeft EyeLookInLeft EyeLookOutLeft EyeLookUpLeft EyeSquintLeft EyeWideLeft
    EyeBlinkRight EyeLookDownRight EyeLookInRight EyeLookOutRight EyeLookUpRight EyeSquintRight EyeWideRight
    JawForward JawLeft JawRight JawOpen MouthClose MouthFunnel MouthPucker MouthLeft MouthRight
    MouthSmileLeft MouthSmileRight MouthFrownLeft MouthFrownRight MouthDimpleLeft MouthDimpleRight
    MouthStretchLeft MouthStretchRight MouthRollLower MouthRollUpper MouthShrugLower MouthShrugUpper
    MouthPressLeft MouthPressRight MouthLowerDownLeft MouthLowerDownRight MouthUpperUpLeft MouthUpperUpRight
    BrowDownLeft BrowDownRight BrowInnerUp BrowOuterUpLeft BrowOuterUpRight CheekPuff CheekSquintLeft
    CheekSquintRight NoseSneerLeft NoseSneerRight TongueOut
    HeadYaw HeadPitch HeadRoll LeftEyeYaw LeftEyePitch LeftEyeRoll RightEyeYaw RightEyePitch RightEyeRoll
""".split()

def _read_livelink(packet: bytes) -> dict:
    offset = 0

    def take(fmt: str):
        nonlocal offset
        values = struct.unpack_from(">" + fmt, packet, offset)
        offset += struct.calcsize(">" + fmt)
        return values

    def string() -> str:
        (length,) = take("i")
        text = take(f"{length}s")[0]
        assert text.endswith(b"\0")  # Unreal's strings count their closing NUL
        return text[:-1].decode("ascii")

    (version,) = take("B")
    device, subject = string(), string()
    frame, sub_frame, numerator, denominator, count = take("ifiiB")
    values = take(f"{count}f")
    assert offset == len(packet)
    return {"version": version, "device": device, "subject": subject, "frame": frame, "sub_frame": sub_frame,
            "rate": (numerator, denominator), "values": values}


def _stream(tmp_path, *links: str) -> list[dict]:
    """Stream the sample with the given link options, and the same frames to a JSON-lines file."""
    frames_file = tmp_path / "frames.jsonl"
    result = subprocess.run([sys.executable, "-m", "prosody", "stream", str(SAMPLE), "-o", str(frames_file),
                             *links], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    return [json.loads(line) for line in frames_file.read_text().splitlines()]


@pytest.mark.slow
def test_livelink_packets_carry_every_frame_with_its_head_brows_and_jaw(tmp_path):
    receiver = _Receiver()
    receiver.start()
    frames = _stream(tmp_path, "--livelink", f"127.0.0.1:{receiver.port}", "--livelink-subject", "Talker 1")
    receiver.join()
    packets = [_read_livelink(d) for d in receiver.datagrams]
    assert len(packets) == len(frames) == 93
    for packet, frame in zip(packets, frames, strict=True):
        assert packet["version"] == 6 and packet["subject"] == "Talker 1" and packet["device"]
        assert packet["frame"] == frame["frame"] and packet["rate"] == (30, 1) and packet["sub_frame"] == 0
        assert len(packet["values"]) == 61
        value = dict(zip(UNREAL_CURVES, packet["values"], strict=True))
        faps = {int(k): v for k, v in frame["faps"].items()}
        for name, fap in (("HeadYaw", 49), ("HeadPitch", 48), ("HeadRoll", 50)):
            assert value[name] == pytest.approx(faps[fap] * RADIANS_PER_AU, abs=1e-5)
        brows = np.clip((faps[31] + faps[32]) / 2 / BROW_FULL_SCALE_ENS, 0, 1)
        assert value["BrowInnerUp"] == pytest.approx(brows, abs=1e-3)
        assert value["JawOpen"] == pytest.approx(np.clip(faps[3] / LIVELINK_FULL_SCALE["jaw"], 0, 1), abs=1e-3)
    # the stream moves: the head turns and the jaw opens while the sample speaks
    assert np.ptp([p["values"][UNREAL_CURVES.index("HeadYaw")] for p in packets]) > 0.01
    assert max(p["values"][UNREAL_CURVES.index("JawOpen")] for p in packets) > 0.1


def test_each_named_value_lands_where_unreal_reads_that_curve():
    values = {name: (k + 1) / 64 for k, name in enumerate(UNREAL_CURVES)}
    packet = _read_livelink(livelink_packet(values, frame=7, fps=29.97, subject="s", device_id="d"))
    assert packet["values"] == pytest.approx([values[name] for name in UNREAL_CURVES])
    assert packet["rate"] == (2997, 100) and packet["frame"] == 7


# OSC 1.0 and the VMC protocol ---------------------------------------------------------------------------------
def _osc_string(data: bytes, offset: int) -> tuple[str, int]:
    end = data.index(b"\0", offset)
    return data[offset:end].decode("utf-8"), (end + 4) & ~3  # NUL-terminated, padded to 4 bytes


def _read_osc_message(data: bytes) -> tuple[str, list]:
    address, offset = _osc_string(data, 0)
    tags, offset = _osc_string(data, offset)
    assert tags.startswith(",")
    args: list = []
    for tag in tags[1:]:
        if tag == "i":
            args.append(struct.unpack_from(">i", data, offset)[0])
            offset += 4
        elif tag == "f":
            args.append(struct.unpack_from(">f", data, offset)[0])
            offset += 4
        elif tag == "s":
            text, offset = _osc_string(data, offset)
            args.append(text)
        else:
            raise AssertionError(f"unexpected OSC type tag {tag!r}")
    assert offset == len(data)
    return address, args


def _read_osc_bundle(data: bytes) -> list[tuple[str, list]]:
    assert data[:8] == b"#bundle\0"
    offset, messages = 16, []  # after the 8-byte time tag
    while offset < len(data):
        (size,) = struct.unpack_from(">i", data, offset)
        messages.append(_read_osc_message(data[offset + 4:offset + 4 + size]))
        offset += 4 + size
    assert offset == len(data)
    return messages


def _rotate(quaternion, vector) -> np.ndarray:
    return Rotation.from_quat(quaternion).apply(vector)


@pytest.mark.parametrize("perfect_sync", [False, True])
@pytest.mark.slow
def test_vmc_bundles_move_the_head_bone_and_the_face(tmp_path, perfect_sync):
    receiver = _Receiver()
    receiver.start()
    frames = _stream(tmp_path, "--vmc", f"127.0.0.1:{receiver.port}", *(["--vmc-perfect-sync"] * perfect_sync))
    receiver.join()
    bundles = [_read_osc_bundle(d) for d in receiver.datagrams]
    assert len(bundles) == len(frames)
    for bundle, frame in zip(bundles, frames, strict=True):
        by_address: dict[str, list] = {}
        for address, args in bundle:
            by_address.setdefault(address, []).append(args)
        assert by_address["/VMC/Ext/OK"] == [[1]]
        assert by_address["/VMC/Ext/T"][0][0] == pytest.approx(frame["time_s"], abs=1e-4)
        assert bundle[-1] == ("/VMC/Ext/Blend/Apply", [])  # applied after every value
        [[bone, *position_and_rotation]] = by_address["/VMC/Ext/Bone/Pos"]
        assert bone == "Head" and position_and_rotation[:3] == [0, 0, 0]
        quaternion = position_and_rotation[3:]
        assert math.isclose(np.linalg.norm(quaternion), 1, abs_tol=1e-5)
        faps = {int(k): v for k, v in frame["faps"].items()}
        expected = unity_head_rotation(faps[49] * RADIANS_PER_AU, faps[48] * RADIANS_PER_AU,
                                       faps[50] * RADIANS_PER_AU)
        assert abs(np.dot(quaternion, expected)) == pytest.approx(1, abs=1e-5)
        blends = {args[0]: args[1] for args in by_address["/VMC/Ext/Blend/Val"]}
        if perfect_sync:
            assert set(blends) == set(LIVELINK_PACKET_BLENDSHAPES)
            brows = np.clip((faps[31] + faps[32]) / 2 / BROW_FULL_SCALE_ENS, 0, 1)
            assert blends["BrowInnerUp"] == pytest.approx(brows, abs=1e-3)
        else:
            assert set(blends) == {"A", "I", "U", "E", "O", "Blink_L", "Blink_R"}
        assert all(0 <= v <= 1 for v in blends.values())
    if not perfect_sync:
        assert max(dict((a[0], a[1]) for _, a in b if len(a) == 2)["A"] for b in bundles) > 0.1


@pytest.mark.parametrize("yaw, pitch, roll, vector, expected", [
    # yaw + turns the face to the character's left: Unity's -X (the avatar faces +Z, its right on +X)
    (0.3, 0, 0, (0, 0, 1), (-math.sin(0.3), 0, math.cos(0.3))),
    # pitch + bows the head: the face turns down (-Y)
    (0, 0.2, 0, (0, 0, 1), (0, -math.sin(0.2), math.cos(0.2))),
    # roll + tilts the top of the head to the character's right (+X)
    (0, 0, 0.1, (0, 1, 0), (math.sin(0.1), math.cos(0.1), 0)),
])
def test_unity_head_rotation_turns_the_avatar_as_the_faps_say(yaw, pitch, roll, vector, expected):
    assert _rotate(unity_head_rotation(yaw, pitch, roll), vector) == pytest.approx(expected, abs=1e-12)


def test_unity_head_rotation_composes_as_unity_does():
    # Unity applies Euler angles Z, then X, then Y: the intrinsic rotation Y-X-Z
    for yaw, pitch, roll in [(0.3, -0.2, 0.15), (-0.5, 0.4, -0.3)]:
        reference = Rotation.from_euler("YXZ", [-yaw, pitch, -roll]).as_quat()
        assert abs(np.dot(unity_head_rotation(yaw, pitch, roll), reference)) == pytest.approx(1, abs=1e-12)


def test_a_target_that_is_not_listening_loses_frames_but_not_the_stream(tmp_path):
    closed = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    closed.bind(("127.0.0.1", 0))
    port = closed.getsockname()[1]
    closed.close()
    frames = _stream(tmp_path, "--livelink", f"127.0.0.1:{port}", "--vmc", f"127.0.0.1:{port}")
    assert len(frames) == 93


@pytest.mark.slow
def test_ipv6_targets_are_sent_to():
    if not socket.has_ipv6:
        pytest.skip("no IPv6 on this machine")
    try:
        receiver = _Receiver(socket.AF_INET6, "::1")
    except OSError:
        pytest.skip("no IPv6 loopback on this machine")
    receiver.start()
    code = main(["stream", str(SAMPLE), "--vmc", f"[::1]:{receiver.port}"])
    receiver.join()
    assert code == 0 and len(receiver.datagrams) == 93


@pytest.mark.parametrize("argv, message", [
    (["--vmc-perfect-sync", "-o", "-"], "give --vmc too"),
    (["--livelink-subject", "x", "-o", "-"], "give --livelink too"),
    (["--livelink", "127.0.0.1", "--livelink-subject", "caf\u00e9"], "printable ASCII"),
    (["--livelink", "127.0.0.1:99999"], "must be in 0-65535"),
    (["--livelink", "127.0.0.1:0"], "no port to send to"),
    (["--vmc", "127.0.0.1:port"], "must be HOST:PORT"),
    (["--vmc", "no-such-host.invalid"], "cannot resolve"),
    (["--livelink", "[::1"], "target '[::1' must be HOST[:PORT]"),
    (["--livelink", ""], "target '' must be HOST[:PORT]"),
    (["--vmc", "::1"], "target '::1' must be HOST[:PORT]"),
    (["-o", "-", "--listen", "[::1"], "listen address '[::1' must be HOST:PORT"),
    (["-o", "-", "--listen", "127.0.0.1:0", "--allow-origin", "http://[::1"], "origin 'http://[::1' must be"),
])
def test_link_usage_errors_exit_2_with_one_line(argv, message, capsys):
    code = main(["stream", str(SAMPLE), *argv])
    assert code == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_links_need_an_input(capsys):
    assert main(["stream", "--listen", "127.0.0.1:0", "--vmc", "127.0.0.1"]) == 2
    assert "send the frames of an input" in capsys.readouterr().err
