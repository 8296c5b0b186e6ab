"""This machine's loopback: the address deepphy's servers listen on unless told otherwise, and
the one test of whether a host or URL names it (the web pages' guard, a model entry that may
receive the request's context, the test model server).

`deepphy --help` reads `LOOPBACK_HOST` for its defaults: the address parsers are imported by
the checks that use them, so that a help's start does not wait for them.
"""

from __future__ import annotations

# Where a server listens by default: this machine only (DEVELOPERS.md: servers bind 127.0.0.1
# by default); also Ray's name for a local node when none is given (deepphy.local_ray).
LOOPBACK_HOST = "127.0.0.1"


def is_loopback(host: str) -> bool:
    """Whether a host name (as listened on, or as a request's Host or Origin names it) is this
    machine's loopback: localhost, 127.0.0.0/8, ::1 (bracketed or not)."""
    import ipaddress  # not at the top: `deepphy --help` imports this module for LOOPBACK_HOST

    if host.lower() in ("localhost", "localhost."):
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def is_loopback_url(url: str) -> bool:
    """Whether a URL's host is this machine's loopback (a URL without a host is not)."""
    from urllib.parse import urlsplit  # not at the top: as ipaddress above

    return is_loopback(urlsplit(url).hostname or "")
