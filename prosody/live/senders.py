"""Live frames sent over UDP to Unreal's Live Link (Live Link Face packets) and to VMC marionettes.

A :class:`LinkSender` is given the frames as :class:`prosody.live.converter.LiveConverter` makes them and sends
one datagram per frame to each of its targets, as soon as it has them. UDP does not wait for a receiver: a
target that is not listening (yet) loses those frames, and the first send error is reported once.
"""

from __future__ import annotations

import socket
from collections.abc import Callable, Iterable, Sequence

import numpy as np

from ..errors import ConfigError
from ..fap.exporters import livelink_columns
from ..fap.live_links import LIVELINK_PORT, VMC_PORT, check_link_name, livelink_packet, vmc_bundle
from ..fap.stream import FapStream
from ..net import parse_address
from .converter import LiveFrame

PROTOCOLS = {"livelink": LIVELINK_PORT, "vmc": VMC_PORT}


def parse_target(text: str, default_port: int) -> tuple[str, int]:
    """``HOST[:PORT]``, ``:PORT`` or ``[IPV6][:PORT]`` -> (host, port); the host defaults to 127.0.0.1.

    Examples
    --------
    >>> parse_target("192.168.1.20", 11111), parse_target(":9000", 11111), parse_target("[::1]:5", 1)
    (('192.168.1.20', 11111), ('127.0.0.1', 9000), ('::1', 5))
    """
    has_port = "]:" in text if text.startswith("[") else text.count(":") == 1
    if not text.strip() or (text.startswith("[") and "]" not in text) or (not text.startswith("[")
                                                                          and text.count(":") > 1):
        raise ConfigError(f"target {text!r} must be HOST[:PORT], e.g. 192.168.1.20:{default_port} ([::1]:"
                          f"{default_port} for IPv6)")
    host, port = parse_address(text if has_port else f"{text}:{default_port}", address_of="target")
    if port == 0:
        raise ConfigError(f"target {text!r}: port 0 is no port to send to (1-65535)")
    return host, port


class LinkSender:
    """Sends each frame to its targets in one protocol: ``livelink`` or ``vmc``.

    Parameters
    ----------
    protocol : {"livelink", "vmc"}
    targets : HOST[:PORT] strings or (host, port) pairs
        Where to send (the protocol's usual port when none is given: 11111 for Live Link, 39539 for VMC).
    fps : float
        The frames' rate, sent in Live Link's frame times.
    subject : str
        Live Link's subject name (the name Unreal lists the source under).
    perfect_sync : bool
        VMC: send the 52 ARKit blendshapes instead of VRM's presets.
    report : callable
        Given a line once when sending first fails.
    """

    def __init__(self, protocol: str, targets: Iterable[str | tuple[str, int]], *, fps: float,
                 subject: str = "prosody", device_id: str = "visual-prosody", perfect_sync: bool = False,
                 report: Callable[[str], None] | None = None) -> None:
        if protocol not in PROTOCOLS:
            raise ConfigError(f"protocol must be one of {', '.join(PROTOCOLS)}, got {protocol!r}")
        self.protocol = protocol
        self.fps = float(fps)
        self.subject = check_link_name(subject, "subject name")
        self.device_id = check_link_name(device_id, "device id")
        self.perfect_sync = perfect_sync
        self.report = report
        self.addresses = [self._resolve(target) for target in targets]
        if not self.addresses:
            raise ConfigError(f"{protocol}: give at least one target")
        self.sockets: dict[int, socket.socket] = {}
        self.sent = 0
        self.failed = 0

    def _resolve(self, target: str | tuple[str, int]) -> tuple[int, tuple]:
        host, port = (parse_target(target, PROTOCOLS[self.protocol]) if isinstance(target, str) else target)
        try:
            family, _, _, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)[0]
        except (socket.gaierror, UnicodeError) as error:
            raise ConfigError(f"{self.protocol} target {host}:{port}: cannot resolve the host ({error})") from None
        return family, address

    def _socket(self, family: int) -> socket.socket:
        if family not in self.sockets:
            self.sockets[family] = socket.socket(family, socket.SOCK_DGRAM)
        return self.sockets[family]

    def datagrams(self, frames: Sequence[LiveFrame]) -> list[bytes]:
        """The datagram of each frame."""
        if not frames:
            return []
        faps = sorted(frames[0].faps)
        stream = FapStream.from_curves({fap: np.array([frame.faps[fap] for frame in frames]) for fap in faps},
                                       fps=self.fps,
                                       n_frames=len(frames))
        columns = livelink_columns(stream)
        out = []
        for k, frame in enumerate(frames):
            values = {name: float(column[k]) for name, column in columns.items()}
            if self.protocol == "livelink":
                out.append(livelink_packet(values, frame=frame.frame, fps=self.fps, subject=self.subject,
                                           device_id=self.device_id))
            else:
                out.append(vmc_bundle(values, time_s=frame.time_s, perfect_sync=self.perfect_sync))
        return out

    def send(self, frames: Sequence[LiveFrame]) -> None:
        for datagram in self.datagrams(frames):
            for family, address in self.addresses:
                try:
                    self._socket(family).sendto(datagram, address)
                    self.sent += 1
                except OSError as error:
                    self.failed += 1
                    if self.failed == 1 and self.report is not None:
                        self.report(f"{self.protocol}: sending to {address[0]}:{address[1]} failed ({error}); "
                                    "frames go on being sent")

    def close(self) -> None:
        for sock in self.sockets.values():
            sock.close()
        self.sockets.clear()
