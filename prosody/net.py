"""What the live page's server and the study's server share: addresses, the origins they answer, the headers
of what they serve, and serving until Ctrl-C.

Both answer only requests that name this machine and pages of their own: a browser names the page that sends
a request in its ``Origin`` header, and a page of another site is refused. A page's own origin is
``http://HOST:PORT`` where HOST is an address (``127.0.0.1``, ``[::1]``, the listening address), ``localhost``
or this machine's name: a name some other site's DNS could point at this machine is not trusted (DNS
rebinding). More origins are allowed by name (``--allow-origin``). Programs, which send no ``Origin``, are
served.

Examples
--------
>>> policy = OriginPolicy(["https://lab.example.org"])
>>> policy.serves_host("127.0.0.1:8765"), policy.serves_host("evil.example.com:8765")
(True, False)
>>> policy.allows("http://127.0.0.1:8765", "127.0.0.1:8765"), policy.allows("https://evil.example.com", "127.0.0.1")
(True, False)
"""

from __future__ import annotations

import ipaddress
import socket
import time
import urllib.parse
from collections.abc import Callable, Iterable

from .errors import ConfigError

__all__ = ["SAFE_HEADERS", "OriginPolicy", "normalize_origin", "parse_address", "serve_until_interrupted",
           "trusted_host"]

#: Headers of everything either server sends: never cached, never sniffed as another type, no referrer sent on.
SAFE_HEADERS = {"Cache-Control": "no-store", "X-Content-Type-Options": "nosniff", "Referrer-Policy": "no-referrer"}


def normalize_origin(text: str) -> str:
    """``scheme://host[:port]`` in lower case, without a default port or a trailing slash.

    Examples
    --------
    >>> normalize_origin("HTTP://LocalHost:80/"), normalize_origin("https://example.org:8443")
    ('http://localhost', 'https://example.org:8443')
    """
    try:
        parts = urllib.parse.urlsplit(text.strip())
        hostname = parts.hostname
    except ValueError:  # an unclosed IPv6 bracket
        raise ConfigError(f"origin {text!r} must be http(s)://HOST[:PORT], e.g. http://localhost:8080") from None
    if parts.scheme not in ("http", "https") or not hostname:
        raise ConfigError(f"origin {text!r} must be http(s)://HOST[:PORT], e.g. http://localhost:8080")
    try:
        port = parts.port
    except ValueError:
        raise ConfigError(f"origin {text!r} has a bad port") from None
    host = f"[{hostname}]" if ":" in hostname else hostname
    default = {"http": 80, "https": 443}[parts.scheme]
    return f"{parts.scheme}://{host}" + ("" if port in (None, default) else f":{port}")


def trusted_host(name: str) -> bool:
    """A host name that no other site can point at this machine: an address, localhost, this machine's name."""
    try:
        ipaddress.ip_address(name.strip("[]"))
        return True
    except ValueError:
        return name.lower() in {"localhost", socket.gethostname().lower(), socket.getfqdn().lower()}


class OriginPolicy:
    """Which requests a server answers: those naming this machine (or an allowed origin's host), from its own
    pages (or an allowed origin's), or from programs.

    Parameters
    ----------
    allow_origins : iterable of str
        Origins of other sites' pages allowed as well (``http(s)://HOST[:PORT]``).
    """

    def __init__(self, allow_origins: Iterable[str] = ()) -> None:
        self.allowed = frozenset(normalize_origin(origin) for origin in allow_origins)
        self._allowed_hosts = {urllib.parse.urlsplit(origin).hostname for origin in self.allowed}

    def serves_host(self, host_header: str) -> bool:
        """Whether a request's ``Host`` names this server: an address, localhost, this machine's name, or the
        host of an allowed origin.

        Parameters
        ----------
        host_header : str

        Returns
        -------
        bool
        """
        try:
            hostname = urllib.parse.urlsplit(normalize_origin(f"http://{host_header}")).hostname or ""
        except (ConfigError, ValueError):
            return False
        return trusted_host(hostname) or hostname in self._allowed_hosts

    def allows(self, origin: str | None, host_header: str) -> bool:
        """Whether a request sent by the page at ``origin`` (None: not a browser's page) to ``host_header`` is
        answered: the server's own page, on a host no other site can claim, or an allowed origin.

        Parameters
        ----------
        origin : str or None
        host_header : str

        Returns
        -------
        bool
        """
        if origin is None:
            return True
        try:
            origin = normalize_origin(origin)
            if origin in self.allowed:
                return True
            own = normalize_origin(f"http://{host_header}")  # the page served here: same host and port
        except ConfigError:
            return False
        return origin == own and trusted_host(urllib.parse.urlsplit(origin).hostname or "")


def parse_address(text: str, address_of: str = "listen address") -> tuple[str, int]:
    """``HOST:PORT``, ``:PORT`` or ``PORT`` (host 127.0.0.1); ``[::1]:PORT`` for IPv6.

    Examples
    --------
    >>> parse_address("8765"), parse_address("0.0.0.0:80"), parse_address("[::1]:9000")
    (('127.0.0.1', 8765), ('0.0.0.0', 80), ('::1', 9000))
    """
    form = ConfigError(f"{address_of} {text!r} must be HOST:PORT, e.g. 127.0.0.1:8765 ([::1]:8765 for IPv6)")
    host, _, port = text.strip().rpartition(":")
    if host.startswith("[") or host.endswith("]"):
        if not (host.startswith("[") and host.endswith("]")):
            raise form
        host = host[1:-1]
        try:
            ipaddress.IPv6Address(host)
        except ValueError:
            raise form from None
    elif ":" in host or any(c in host for c in "[]/ ") or not port.isdigit() or len(port) > 5:
        raise form
    host = host or "127.0.0.1"
    try:
        number = int(port)
    except ValueError:
        raise form from None
    if not 0 <= number <= 65535:
        raise ConfigError(f"{address_of} {text!r}: port {number} must be in 0-65535")
    return host, number


def serve_until_interrupted(close: Callable[[], object]) -> None:
    """Block the calling thread until Ctrl-C (or SIGTERM, which the command turns into it), then ``close``."""
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        pass
    finally:
        close()
