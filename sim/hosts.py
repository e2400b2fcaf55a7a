"""The addresses of this machine a server may serve on, and the web origins it may answer, checked with
nothing but the standard library (the command line checks ``--host`` and ``--allow-origin`` with them
before any work).

A host is checked by resolving it and binding each of its addresses to port 0 (nothing listens, nothing is
sent): a name that does not resolve or an address of another machine is one clear error. The browser viewer
(:mod:`besman.sim.serving`) would otherwise try such a host on 1000 ports and then wait forever.
"""

from __future__ import annotations

import errno
import ipaddress
import socket
import struct
from collections.abc import Iterable
from pathlib import Path
from urllib.parse import urlsplit

from besman.core.errors import InputError

SIOCGIFADDR = 0x8915  # Linux ioctl: an interface's IPv4 address


def host_addresses(host: str) -> list[str]:
    """The addresses ``host`` names, each one this machine can serve on; an :class:`InputError` naming the
    host and the reason if it does not resolve or names an address that is not this machine's."""
    if not isinstance(host, str) or not host.strip():
        raise InputError(f"the viewer's host must be an address or name of this machine, got {host!r}")
    mapped = _mapped(host)
    if mapped is not None:  # viser's server does not come up on one (it hung)
        raise InputError(f"host {host}: an IPv4 address written as IPv6; give it as {mapped}")
    try:
        found = socket.getaddrinfo(host, 0, type=socket.SOCK_STREAM)
    except (OSError, UnicodeError) as error:
        raise InputError(f"host {host}: cannot resolve it ({_reason(error)})") from None
    addresses = []
    for family, kind, protocol, _, address in found:
        with socket.socket(family, kind, protocol) as probe:
            try:
                probe.bind(address)  # port 0: nothing listens, nothing is sent
            except OSError as error:
                where = "" if address[0] == host else f" ({address[0]})"
                mine = error.errno != errno.EADDRNOTAVAIL
                reason = "cannot serve on it" if mine else "not an address of this machine"
                raise InputError(f"host {host}{where}: {reason} ({_reason(error)})") from None
        addresses.append(address[0])
    return addresses


def _mapped(host: str) -> str | None:
    """The IPv4 address that ``host`` writes as an IPv4-mapped IPv6 address (``::ffff:127.0.0.1``), if so."""
    try:
        mapped = getattr(ipaddress.ip_address(host.strip("[]")), "ipv4_mapped", None)
    except ValueError:
        return None
    return None if mapped is None else str(mapped)


def _reason(error: BaseException) -> str:
    return getattr(error, "strerror", None) or str(error)


def _ip(address: str) -> ipaddress.IPv4Address | ipaddress.IPv6Address:
    ip = ipaddress.ip_address(address.split("%")[0])
    mapped = getattr(ip, "ipv4_mapped", None)
    return mapped if mapped is not None else ip


def loopback_only(addresses: Iterable[str]) -> bool:
    """Whether every address is a loopback one (served to this machine alone)."""
    return all(_ip(address).is_loopback for address in addresses)


def network_addresses(version: int = 4) -> list[str]:
    """This machine's addresses other than loopback and link-local ones, IPv4 or IPv6 (Linux)."""
    found = []
    if version == 4:
        import fcntl

        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            for _, name in socket.if_nameindex():
                try:
                    request = struct.pack("256s", name.encode()[:15])
                    found.append(socket.inet_ntoa(fcntl.ioctl(probe.fileno(), SIOCGIFADDR, request)[20:24]))
                except OSError:
                    continue  # no IPv4 address
    else:
        try:
            lines = Path("/proc/net/if_inet6").read_text().splitlines()
        except OSError:
            lines = []
        found = [str(ipaddress.IPv6Address(int(line.split()[0], 16))) for line in lines]
    addresses = [ipaddress.ip_address(a) for a in found]
    return [str(a) for a in addresses if not (a.is_loopback or a.is_link_local)]


def url(host: str, port: int, addresses: list[str]) -> str:
    """The address to open in a browser: ``host`` itself, or for a wildcard host (every address of this
    machine) its first network address (its host name if it has none)."""
    name = host
    if addresses and all(_ip(address).is_unspecified for address in addresses):
        version = _ip(addresses[0]).version
        name = next(iter(network_addresses(version)), socket.gethostname())
    return f"http://{f'[{name}]' if ':' in name else name}:{port}"


def origin(text: str) -> str | None:
    """``text`` as a web origin, ``scheme://host[:port]`` in lower case without a default port, or None if
    it is none (``null``, a path, a query)."""
    try:
        parts = urlsplit(text.strip())
        port = parts.port
    except ValueError:
        return None
    if parts.scheme not in ("http", "https") or not parts.hostname or parts.path not in ("", "/"):
        return None
    if parts.query or parts.fragment or parts.username is not None:
        return None
    host = f"[{parts.hostname}]" if ":" in parts.hostname else parts.hostname
    default = {"http": 80, "https": 443}[parts.scheme]
    return f"{parts.scheme}://{host}" + (f":{port}" if port not in (None, default) else "")


def origins(texts: Iterable[str]) -> set[str]:
    """Web origins (:func:`origin`) from a list of them; an :class:`InputError` names one that is none."""
    if isinstance(texts, str):
        raise InputError(f"allowed origins must be a list of origins, got the string {texts!r}")
    found = set()
    for text in texts:
        if not isinstance(text, str) or origin(text) is None:
            raise InputError(
                f"allowed origin {text!r}: expected scheme://host[:port], e.g. https://viewer.example.org"
            )
        found.add(origin(text))
    return found
