"""Frames as the live tools of animators and VTubers receive them: Live Link Face packets and VMC messages.

Both take the weights and angles of :func:`prosody.fap.exporters.livelink_columns` (the Live Link Face CSV
mapping: 52 ARKit blendshape weights in [0, 1], head angles in radians with the FAPs' signs) for one frame.

**Live Link Face** (Epic Games' iPhone app, read by Unreal's Live Link plug-in on UDP port 11111). One datagram
per frame, big-endian::

    uint8    packet version (6)
    int32    length of the device id, counting its closing NUL, then its ASCII bytes and the NUL
    int32    length of the subject name, the same way, then its bytes and the NUL
    int32    frame number            \\  the frame's time: frame number + sub-frame
    float32  sub-frame (0)           /   at the frame rate numerator / denominator
    int32    frame rate numerator
    int32    frame rate denominator
    uint8    value count (61)
    61 x float32: the 52 blendshapes in the order of Unreal's ``EARFaceBlendShape`` (which differs from the
             app's CSV in Jaw/Mouth Left and Right), then HeadYaw, HeadPitch, HeadRoll and the six eye angles

**VMC protocol** (VSeeFace, VMagicMirror, Warudo and other "marionettes", usually on UDP port 39539): one OSC
bundle per frame with ``/VMC/Ext/OK 1``, ``/VMC/Ext/T time``, ``/VMC/Ext/Bone/Pos "Head" 0 0 0 qx qy qz qw``
(the head's local rotation in Unity's axes: left-handed, Y up, the avatar facing +Z), one
``/VMC/Ext/Blend/Val name value`` per blendshape and ``/VMC/Ext/Blend/Apply``. The blendshapes are VRM 0.x's
presets (``A I U E O`` from the mouth, ``Blink_L Blink_R``), or with ``perfect_sync`` the 52 ARKit names
that "perfect sync" avatars carry (the only way brows reach a VRM avatar: its presets have none).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Mapping
from fractions import Fraction

import numpy as np

from ..errors import ConfigError
from .exporters import ARKIT_BLENDSHAPES, LIVELINK_ROTATIONS

LIVELINK_PORT = 11111
VMC_PORT = 39539
LIVELINK_PACKET_VERSION = 6
#: The 52 blendshapes in the order of Unreal's EARFaceBlendShape, the order of the packet's values: the CSV's
#: order, but for JawLeft before JawRight and MouthLeft before MouthRight.
_UNREAL_SWAPS = {"JawRight": "JawLeft", "JawLeft": "JawRight", "MouthRight": "MouthLeft", "MouthLeft": "MouthRight"}
LIVELINK_PACKET_BLENDSHAPES = tuple(_UNREAL_SWAPS.get(name, name) for name in ARKIT_BLENDSHAPES)
LIVELINK_PACKET_ROTATIONS = LIVELINK_ROTATIONS
#: Names the packet's strings may hold: printable ASCII, at most this long.
MAX_NAME_LENGTH = 255


def check_link_name(name: str, what: str) -> str:
    """A device id or subject name that every receiver reads the same way: 1-255 printable ASCII characters."""
    if not name or len(name) > MAX_NAME_LENGTH or not all(" " <= c <= "~" for c in name):
        raise ConfigError(f"{what} {name!r} must be 1-{MAX_NAME_LENGTH} printable ASCII characters")
    return name


def frame_rate_fraction(fps: float) -> tuple[int, int]:
    """The frame rate as Unreal's numerator / denominator (29.97 -> 2997/100, 30 -> 30/1)."""
    rate = Fraction(fps).limit_denominator(1001)
    return rate.numerator, rate.denominator


def _unreal_string(text: str) -> bytes:
    data = text.encode("ascii") + b"\0"
    return struct.pack(">i", len(data)) + data


def livelink_packet(values: Mapping[str, float], *, frame: int, fps: float, subject: str,
                    device_id: str) -> bytes:
    """One Live Link Face datagram (layout in the module docstring); names missing from ``values`` send 0.

    Examples
    --------
    >>> packet = livelink_packet({"JawOpen": 0.5}, frame=3, fps=30, subject="prosody", device_id="dev")
    >>> len(packet), packet[0]
    (282, 6)
    """
    numerator, denominator = frame_rate_fraction(fps)
    names = (*LIVELINK_PACKET_BLENDSHAPES, *LIVELINK_PACKET_ROTATIONS)
    floats = [float(values.get(name, 0.0)) for name in names]
    return b"".join((struct.pack(">B", LIVELINK_PACKET_VERSION), _unreal_string(device_id), _unreal_string(subject),
                     struct.pack(">ifiiB", frame, 0.0, numerator, denominator, len(names)),
                     struct.pack(f">{len(names)}f", *floats)))


def unity_head_rotation(yaw_rad: float, pitch_rad: float, roll_rad: float) -> tuple[float, float, float, float]:
    """The head's rotation as a Unity quaternion ``(x, y, z, w)`` from the FAPs' angles (yaw + to the
    character's left, pitch + down, roll + to its right).

    Unity is left-handed, Y up, and an avatar faces +Z with its right on +X: a rotation about +Y turns it to
    its right, about +X bows it, about +Z tilts it to its left. Unity composes Euler angles Z, then X, then Y.
    """
    def axis(index: int, angle: float) -> np.ndarray:
        q = np.zeros(4)
        q[index] = math.sin(angle / 2)
        q[3] = math.cos(angle / 2)
        return q

    def product(a: np.ndarray, b: np.ndarray) -> np.ndarray:  # Hamilton product of (x, y, z, w)
        (ax, ay, az, aw), (bx, by, bz, bw) = a, b
        return np.array([aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                         aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz])

    q = product(product(axis(1, -yaw_rad), axis(0, pitch_rad)), axis(2, -roll_rad))
    x, y, z, w = (float(v) for v in q)
    return x, y, z, w


def vrm_presets(values: Mapping[str, float]) -> dict[str, float]:
    """VRM 0.x's mouth and blink presets from the ARKit weights: a rough map, as the presets are vowels.

    ``A`` the jaw's opening that is not rounded, ``O`` the open rounded lips (funnel), ``U`` the closed rounded
    ones (pucker), ``I`` and ``E`` the spread lips (stretch) closed and open; ``Blink_L``/``Blink_R`` the eyelids.
    """
    def get(name: str) -> float:
        return float(values.get(name, 0.0))

    opening = get("JawOpen")
    rounded = min(1.0, get("MouthPucker") + get("MouthFunnel"))
    spread = (get("MouthStretchLeft") + get("MouthStretchRight")) / 2
    return {"A": opening * (1 - rounded), "I": spread * (1 - opening), "U": get("MouthPucker"),
            "E": spread * opening, "O": get("MouthFunnel"), "Blink_L": get("EyeBlinkLeft"),
            "Blink_R": get("EyeBlinkRight")}


def vmc_bundle(values: Mapping[str, float], *, time_s: float, perfect_sync: bool = False) -> bytes:
    """One VMC frame as an OSC bundle (contents in the module docstring)."""
    from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder
    from pythonosc.osc_message_builder import OscMessageBuilder

    def message(address: str, *args: tuple[str | float, str]):
        builder = OscMessageBuilder(address)
        for value, kind in args:
            builder.add_arg(value, kind)
        return builder.build()

    head = unity_head_rotation(values.get("HeadYaw", 0.0), values.get("HeadPitch", 0.0),
                               values.get("HeadRoll", 0.0))
    blends = ({name: float(values.get(name, 0.0)) for name in LIVELINK_PACKET_BLENDSHAPES} if perfect_sync
              else vrm_presets(values))
    bundle = OscBundleBuilder(IMMEDIATELY)
    bundle.add_content(message("/VMC/Ext/OK", (1, "i")))
    bundle.add_content(message("/VMC/Ext/T", (float(time_s), "f")))
    bundle.add_content(message("/VMC/Ext/Bone/Pos", ("Head", "s"), *((v, "f") for v in (0.0, 0.0, 0.0, *head))))
    for name, value in blends.items():
        bundle.add_content(message("/VMC/Ext/Blend/Val", (name, "s"), (value, "f")))
    bundle.add_content(message("/VMC/Ext/Blend/Apply"))
    return bundle.build().dgram
