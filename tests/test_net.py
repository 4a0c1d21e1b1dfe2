"""What the live and study servers share: which hosts and pages they answer (one policy for both)."""

from __future__ import annotations

import pytest

from prosody.errors import ConfigError
from prosody.net import OriginPolicy, normalize_origin, parse_address


@pytest.mark.parametrize(("host", "served"), [("127.0.0.1:8765", True), ("[::1]:8766", True), ("localhost", True),
                                              ("lab.example.org:8765", True), ("rebound.example.com:8765", False),
                                              ("", False), ("[::1", False)])
def test_a_server_answers_only_hosts_no_other_site_can_claim(host: str, served: bool) -> None:
    assert OriginPolicy(["https://lab.example.org"]).serves_host(host) is served


@pytest.mark.parametrize(("origin", "host", "allowed"), [
    (None, "127.0.0.1:8765", True),                               # a program, not a browser's page
    ("http://127.0.0.1:8765", "127.0.0.1:8765", True),            # the server's own page
    ("http://127.0.0.1:9999", "127.0.0.1:8765", False),           # another port is another site
    ("https://evil.example.com", "127.0.0.1:8765", False),
    ("http://rebound.example.com:8765", "rebound.example.com:8765", False),  # DNS rebinding: own, yet untrusted
    ("https://LAB.example.org:443/", "", True),                   # allowed by name, even without a Host
    ("not an origin", "127.0.0.1:8765", False)])
def test_a_server_answers_its_own_pages_allowed_origins_and_programs(origin, host, allowed) -> None:
    assert OriginPolicy(["https://lab.example.org"]).allows(origin, host) is allowed


def test_origins_and_addresses_are_refused_in_one_line() -> None:
    with pytest.raises(ConfigError, match="must be http"):
        OriginPolicy(["ftp://lab.example.org"])
    with pytest.raises(ConfigError, match="bad port"):
        normalize_origin("http://lab.example.org:99999")
    with pytest.raises(ConfigError, match="port 70000 must be in 0-65535"):
        parse_address("127.0.0.1:70000")
