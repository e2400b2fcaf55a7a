"""Where the browser viewer serves and whom it answers.

The viewer's host is checked before viser starts (:func:`besman.sim.hosts.host_addresses`): a name that does
not resolve or an address of another machine is one clear error.

viser 1.1 accepts a websocket from any web page: a page the user visits while a viewer runs could open one
to 127.0.0.1, read the scene and drive its controls (cross-site websocket hijacking). :func:`start` starts
viser's server with a check of every websocket handshake's ``Origin`` header (:class:`OriginCheck`), placed
before viser's own ``process_request`` hook of the ``websockets`` server it starts: the one place viser
hands a request over. A refused handshake gets HTTP 403 and never reaches the scene or the GUI. The adapter
fails closed: if viser (another version) did not start its server through that call, :func:`start` stops
it and raises.

It also hides viser's "share" button (it opens a public tunnel through share.viser.studio) and ignores a
client's request for one, and turns what a client can provoke - a request that is not HTTP, frames viser
cannot decode (garbage, bad msgpack, wrong message types), a GUI value it cannot take - into one quiet log
line (logger ``besman.viewer``, level INFO) instead of a traceback on the terminal; the client that sent a
malformed frame is disconnected.
"""

from __future__ import annotations

import asyncio
import http
import ipaddress
import logging
import socket
import threading
import warnings
import weakref
from collections.abc import Iterable
from urllib.parse import urlsplit

import viser
import websockets.asyncio.server

from besman.sim.hosts import origin, origins

log = logging.getLogger("besman.viewer")

# The websocket handler of viser 1.1's server, which the adapter recognises in websockets' serve call.
VISER_HANDLER = "WebsockServer._background_worker.<locals>.ws_handler"

MAX_WARNED = 100  # refused origins named in the log (a page may make up any number of names)

_serve = websockets.asyncio.server.serve  # websockets' own
_starting = threading.Lock()  # one viewer starts at a time, so a serve call is matched to its check
_check: OriginCheck | None = None  # the check of the viewer starting now
_servers: weakref.WeakSet = weakref.WeakSet()  # the viewers' websockets servers (whose logs are quieted)

# viser warns (two lines) about a client message whose fields have the wrong shape; the message then fails.
warnings.filterwarnings("ignore", message=r"\[viser\] .* does not match annotation", module=r"viser\.")


class OriginCheck:
    """Which web pages may open the viewer's websocket. A handshake is accepted when

    - it has no ``Origin`` header: no browser sent it (browsers send one with every websocket handshake),
      and a program on this machine needs no web page to reach the server, so refusing it protects nothing;
    - its ``Origin`` is the page's own: ``http://`` and the ``Host`` the browser sent, where that host is an
      IP address, ``localhost`` or a name of this machine (the address the browser reached: 127.0.0.1, the
      network address, an SSH tunnel's port). Any other name is refused even when it resolves here: a page
      of someone else's name re-pointed at this machine (DNS rebinding) is not the viewer's page;
    - its ``Origin`` is one of ``allowed`` (the viewer's page served through a proxy, e.g.
      ``https://viewer.example.org``).
    """

    def __init__(self, host: str, allowed: Iterable[str] = ()) -> None:
        self.allowed = origins(allowed)
        self.names = {"localhost", host.lower().rstrip("."), socket.gethostname().lower()}
        self.installed = False  # set when the check is in place in a server
        self._refused: set[str] = set()

    def refusal(self, headers) -> str | None:
        """Why a handshake with these request headers is refused; None if it is accepted."""
        if len(headers.get_all("Origin")) > 1 or len(headers.get_all("Host")) > 1:
            return "more than one Origin or Host header"  # no browser sends that: a forged handshake
        sent = headers.get("Origin")
        if sent is None or origin(sent) in self.allowed:
            return None
        host = headers.get("Host", "")
        if origin(sent) is not None and origin(sent) == origin(f"http://{host}") and self._this_machine(host):
            return None
        if sent not in self._refused and len(self._refused) < MAX_WARNED:  # a line per page, however often
            self._refused.add(sent)
            log.warning(
                "besman: warning: the viewer refused a websocket from the page at %.200s (not the viewer's "
                "own page; a proxy's address may be allowed with --allow-origin)",
                sent,
            )
        return f"origin {sent!r} is not this viewer's page"

    def _this_machine(self, host: str) -> bool:
        try:
            name = urlsplit(f"//{host}").hostname
        except ValueError:
            return False
        if not name:
            return False
        try:
            ipaddress.ip_address(name)
            return True  # an address cannot be re-pointed by someone's DNS
        except ValueError:
            return name.rstrip(".") in self.names or name.endswith(".localhost")


def _websocket(request) -> bool:
    return "websocket" in request.headers.get("Upgrade", "").lower()


def _viser_client(request) -> bool:
    """Whether a handshake offers viser's protocol (viser's page does; viser prints a line on stdout for a
    client that does not)."""
    offered = ",".join(request.headers.get_all("Sec-WebSocket-Protocol"))
    return any(protocol.strip().startswith("viser-v") for protocol in offered.split(","))


def _checked_serve(handler, *args, **options):
    """websockets' ``serve`` as viser 1.1 calls it, with the starting viewer's origin check before viser's
    ``process_request`` hook, and its event loop's errors logged quietly."""
    check, hook = _check, options.get("process_request")
    if check is None or hook is None or getattr(handler, "__qualname__", "") != VISER_HANDLER:
        return _serve(handler, *args, **options)

    def process_request(connection, request):
        if not _websocket(request):
            return hook(connection, request)  # the page's files
        refusal = check.refusal(request.headers)
        if refusal is not None:
            return connection.respond(http.HTTPStatus.FORBIDDEN, f"{refusal}\n")
        if not _viser_client(request):
            return connection.respond(http.HTTPStatus.BAD_REQUEST, "not a viser client\n")
        return hook(connection, request)

    asyncio.get_running_loop().set_exception_handler(_log_loop_error)
    served = _serve(handler, *args, **{**options, "process_request": process_request})
    _servers.add(served.server)
    check.installed = True
    return served


def start(host: str, port: int, allowed_origins: Iterable[str] = ()) -> viser.ViserServer:
    """viser's server on ``host`` (an address of this machine: check it first with
    :func:`~besman.sim.hosts.host_addresses`) and ``port`` (busy: the next free one; 0: any), answering
    websocket handshakes only as :class:`OriginCheck` allows."""
    global _check
    check = OriginCheck(host, allowed_origins)
    with _starting:
        _check, websockets.asyncio.server.serve = check, _checked_serve
        try:
            server = viser.ViserServer(host=host, port=port, verbose=False)
        finally:
            _check, websockets.asyncio.server.serve = None, _serve
    if not check.installed:
        server.stop()
        raise RuntimeError(
            f"viser {viser.__version__} does not start its server as viser 1.1 does: besman cannot check "
            "which pages open the viewer's websocket, so it does not serve"
        )
    server.gui.configure_theme(show_share_button=False)
    server.request_share_url = _no_share  # a client's request for a public share link (viser calls this)
    return server


def _no_share(*_, **__) -> None:
    log.info("the viewer ignored a request for a public share link")


def _log_loop_error(loop, context) -> None:
    """The viewer's event loop: an error a client provoked (a GUI value viser cannot cast, a message its
    handler cannot take) is one quiet line."""
    error = context.get("exception")
    log.info("the viewer ignored a client message: %s", _summary(error) if error else context.get("message"))
    log.debug("the error in the viewer's event loop", exc_info=error)


def _summary(error: BaseException) -> str:
    return f"{type(error).__name__}: {str(error)[:200]}"


class _QuietConnections(logging.Filter):
    """websockets logs a viewer connection that broke - a request that is no HTTP, a frame viser cannot
    decode - with a traceback; one quiet line instead (the client is disconnected)."""

    def filter(self, record: logging.LogRecord) -> bool:
        connection = getattr(record, "websocket", None)
        if record.exc_info is None or getattr(connection, "server", None) not in _servers:
            return True
        peer = getattr(connection, "remote_address", None)
        log.info(
            "the viewer dropped a client %s (%s): %s", peer, record.getMessage(), _summary(record.exc_info[1])
        )
        return False


logging.getLogger("websockets.server").addFilter(_QuietConnections())
