"""Nothing besman starts is reachable from the network: the Ray it starts listens on 127.0.0.1 only, and the
viewer answers websockets only from its own page, warns when it serves beyond this machine, and refuses an
address it cannot serve on. Every test runs the real command; no traffic leaves 127.0.0.0/8."""

from __future__ import annotations

import asyncio
import contextlib
import ipaddress
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from pathlib import Path
from urllib.parse import urlsplit

import msgspec
import pytest
import viser
import websockets
import zstandard
from helpers import processes_marked, sigint_by_default
from websockets.asyncio.client import connect

from besman.sim.hosts import network_addresses

ROOT = Path(__file__).resolve().parents[1]
DEMOS = ROOT / "examples" / "data"
SUBPROTOCOL = f"viser-v{viser.__version__}"


# -- who listens where -------------------------------------------------------------------------------------


def _address(text: str, version: int) -> ipaddress.IPv4Address | ipaddress.IPv6Address:
    """An address of /proc/net/{tcp,udp}[6]: hex, in 32-bit words of the host's byte order."""
    raw = bytes.fromhex(text)
    words = [raw[i : i + 4][::-1] for i in range(0, len(raw), 4)]
    return ipaddress.ip_address(b"".join(words)) if version == 6 else ipaddress.ip_address(words[0])


def listening_sockets(pids: set[int]) -> set[tuple[str, str, int]]:
    """(protocol, address, port) of every listening TCP socket and every bound UDP socket that one of
    ``pids`` holds (v4 and v6)."""
    inodes = set()
    for pid in pids:
        try:
            for descriptor in Path(f"/proc/{pid}/fd").iterdir():
                target = os.readlink(descriptor)
                if target.startswith("socket:["):
                    inodes.add(int(target[8:-1]))
        except OSError:
            continue  # ended meanwhile
    found = set()
    for protocol in ("tcp", "tcp6", "udp", "udp6"):
        for line in Path(f"/proc/net/{protocol}").read_text().splitlines()[1:]:
            fields = line.split()
            address, port = fields[1].split(":")
            listening = fields[3] == "0A" if protocol.startswith("tcp") else int(port, 16) != 0
            if listening and int(fields[9]) in inodes:
                found.add(
                    (protocol, str(_address(address, 6 if protocol.endswith("6") else 4)), int(port, 16))
                )
    return found


def loopback(address: str) -> bool:
    ip = ipaddress.ip_address(address)
    mapped = getattr(ip, "ipv4_mapped", None)
    return ip.is_loopback or (mapped is not None and mapped.is_loopback)


def processes_of_run(token: str) -> set[int]:
    """A command started by :func:`start_marked` and every process it started: the marked ones and their
    descendants (Ray's agents, which the raylet starts with an environment of its own)."""
    found = set(processes_marked(token))
    parents = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            parents[int(stat.parent.name)] = int(stat.read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            continue  # ended meanwhile
    while grown := {pid for pid, parent in parents.items() if parent in found} - found:
        found |= grown
    return found


def test_the_loopback_check_sees_a_wildcard_bind():
    """What the Ray test relies on: sockets on every address (TCP v4 and v6, UDP) are seen as exposed, one on
    127.0.0.1 is not. (They listen for a moment, unused.)"""
    with (
        socket.socket() as local,
        socket.socket() as everywhere,
        socket.socket(socket.AF_INET6) as everywhere6,
        socket.socket(type=socket.SOCK_DGRAM) as datagrams,
    ):
        for sock, address in ((local, "127.0.0.1"), (everywhere, "0.0.0.0"), (everywhere6, "::")):
            sock.bind((address, 0))
            sock.listen()
        datagrams.bind(("0.0.0.0", 0))
        found = listening_sockets({os.getpid()})
        port = lambda sock: sock.getsockname()[1]  # noqa: E731
        exposed = {("tcp", "0.0.0.0", port(everywhere)), ("tcp6", "::", port(everywhere6))}
        exposed.add(("udp", "0.0.0.0", port(datagrams)))
        assert ("tcp", "127.0.0.1", port(local)) in found
    assert {entry for entry in found if not loopback(entry[1])} == exposed


@pytest.mark.slow
def test_learn_on_ray_listens_on_this_machine_only(tmp_path):
    """While ``learn --backend ray`` runs, no process of it (the learn, Ray's GCS, raylet and object manager,
    dashboard and agents, workers) listens anywhere but on 127.0.0.0/8 or ::1."""
    pytest.importorskip("ray")
    argv = (
        f"learn --demos {DEMOS} --out {tmp_path / 'pool'} --training-tasks 2 --budget 8 --backend ray".split()
    )
    token, err = uuid.uuid4().hex, tmp_path / "stderr.txt"
    with err.open("w") as stderr:
        process = subprocess.Popen(
            [sys.executable, "-m", "besman", *argv],
            stdout=subprocess.DEVNULL,
            stderr=stderr,
            env={**os.environ, "BESMAN_TEST_TOKEN": token},
            preexec_fn=sigint_by_default,
        )
    seen: set[tuple[str, str, int]] = set()
    try:
        deadline, working_since = time.monotonic() + 180, None
        while time.monotonic() < deadline and process.poll() is None:
            pids = processes_of_run(token)
            seen |= listening_sockets(pids)
            if working_since is None and any(_is_ray_worker(pid) for pid in pids):
                working_since = time.monotonic()
            if working_since is not None and time.monotonic() - working_since > 5:
                break  # Ray's services and workers are up and rolling out blocks
            time.sleep(0.3)
        assert working_since is not None, f"Ray's workers never started:\n{err.read_text()[-3000:]}"
    finally:
        process.send_signal(signal.SIGINT)  # Ctrl-C: Ray's agents end with it (after a SIGKILL they linger)
        try:
            process.wait(timeout=60)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    assert len(seen) >= 4, seen  # the GCS, the raylet's object and node managers, workers
    assert [entry for entry in seen if not loopback(entry[1])] == []
    assert "reachable from the network" not in err.read_text()


def _is_ray_worker(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().startswith(b"ray::")
    except OSError:
        return False


# -- the viewer --------------------------------------------------------------------------------------------


class Served:
    """``besman ARGV`` that ends serving the viewer: its address, everything it has written to stderr so far
    (read as it comes) and to stdout."""

    def __init__(self, *argv: str) -> None:
        self.stdout = tempfile.TemporaryFile("w+")  # noqa: SIM115 (closed by stop)
        self.process = subprocess.Popen(
            [sys.executable, "-m", "besman", *argv],
            stdout=self.stdout,
            stderr=subprocess.PIPE,
            text=True,
            preexec_fn=sigint_by_default,
        )
        self.lines: list[str] = []
        for line in self.process.stderr:
            self.lines.append(line)
            if "until Ctrl-C" in line:
                break
        else:
            raise AssertionError(f"besman {' '.join(argv)} ended without serving:\n{self.err}")
        self.url = re.search(r"http://\S+:\d+", self.lines[-1]).group(0)
        self.port = int(self.url.rsplit(":", 1)[1])
        self._reader = threading.Thread(target=lambda: self.lines.extend(self.process.stderr), daemon=True)
        self._reader.start()

    @property
    def err(self) -> str:
        return "".join(self.lines)

    @property
    def out(self) -> str:
        self.stdout.seek(0)
        return self.stdout.read()

    def stop(self) -> str:
        """Ctrl-C: the command ends as every command does (exit 130, ``besman: interrupted``); returns its
        stderr."""
        self.process.send_signal(signal.SIGINT)
        self.process.wait(timeout=60)
        self._reader.join(timeout=10)
        self.stdout.close()
        assert self.process.returncode == 130, self.err[-3000:]
        assert self.err.splitlines()[-1:] == ["besman: interrupted"], self.err[-3000:]
        return self.err


def frames(frame: bytes) -> list[dict]:
    """The messages of one frame from viser's server: sizes, zstd-compressed msgpack, binary buffers."""
    size, compressed = int.from_bytes(frame[:8], "little"), int.from_bytes(frame[8:16], "little")
    inner = zstandard.ZstdDecompressor().decompress(frame[16 : 16 + compressed], max_output_size=size)
    return msgspec.msgpack.decode(inner)["messages"]


async def opened(port: int, origin: str | None, *, host: str = "127.0.0.1", send=()) -> list[dict]:
    """A websocket to the viewer on 127.0.0.1:``port`` as a browser that reached it by the name ``host`` (the
    request's Host header; no name is looked up) opens it from the page at ``origin`` (None: no Origin
    header): the messages of the server's first frames, after sending ``send``. A refused handshake raises
    InvalidStatus."""
    received = []
    async with connect(
        f"ws://{host}:{port}",
        sock=socket.create_connection(("127.0.0.1", port)),
        subprotocols=[SUBPROTOCOL],
        origin=origin,
        max_size=None,
        open_timeout=30,
    ) as websocket:
        received += frames(await asyncio.wait_for(websocket.recv(), 30))
        for message in send:
            await websocket.send(message)
            await asyncio.sleep(0.05)
        with contextlib.suppress(TimeoutError, websockets.ConnectionClosed):
            while True:
                received += frames(await asyncio.wait_for(websocket.recv(), 0.3))
    return received


async def handshake(uri: str, **options) -> None:
    """A websocket handshake, nothing more."""
    async with connect(uri, **options):
        pass


@pytest.fixture(scope="module")
def run_log(tmp_path_factory) -> Path:
    """A run's log to replay (the gallery's grasp-then-place)."""
    log = tmp_path_factory.mktemp("log") / "run.jsonl"
    subprocess.run(
        [sys.executable, "-m", "besman", "demo", "--log", str(log)], check=True, capture_output=True
    )
    return log


@pytest.fixture(scope="module")
def replay(run_log):
    """``besman view --replay`` on this machine, with a proxy's page allowed; ends with no traceback."""
    served = Served(
        "view", "--replay", str(run_log), "--port", "0", "--allow-origin", "https://viewer.example.org"
    )
    yield served
    err = served.stop()
    assert "Traceback" not in err and "Task failed" not in err, err[-3000:]


@pytest.mark.slow  # a command that serves the viewer: seconds to start
def test_a_websocket_from_another_page_is_refused_and_the_viewers_own_accepted(replay):
    own = f"http://127.0.0.1:{replay.port}"
    assert replay.url == own  # served to this machine alone: no warning
    assert "reachable from the network" not in replay.err
    scene = asyncio.run(opened(replay.port, own))
    assert any(message["type"] == "GuiSliderMessage" for message in scene)  # the replay's timeline
    localhost = f"http://localhost:{replay.port}"
    assert asyncio.run(opened(replay.port, localhost, host="localhost"))  # the page by this machine's name
    assert asyncio.run(opened(replay.port, None))  # no Origin: no browser, no page to refuse
    assert asyncio.run(opened(replay.port, "https://viewer.example.org"))  # --allow-origin
    for host, foreign in (
        ("127.0.0.1", "http://evil.example"),
        ("127.0.0.1", localhost),  # not the page the browser is on
        ("127.0.0.1", f"http://127.0.0.1:{replay.port + 1}"),  # another server of this machine
        ("127.0.0.1", f"https://127.0.0.1:{replay.port}"),
        ("127.0.0.1", "null"),  # a sandboxed frame, a file
        ("evil.example", f"http://evil.example:{replay.port}"),  # someone's name pointed here (DNS rebinding)
        ("127.0.0.1", "http://evil.example"),  # again: refused again, warned once
    ):
        with pytest.raises(websockets.InvalidStatus) as refused:
            asyncio.run(opened(replay.port, foreign, host=host))
        assert refused.value.response.status_code == 403, foreign
    time.sleep(0.5)
    warned = [line for line in replay.lines if "from the page at http://evil.example (" in line]
    assert warned == [  # one line per page, however often it tries
        "besman: warning: the viewer refused a websocket from the page at http://evil.example (not the "
        "viewer's own page; a proxy's address may be allowed with --allow-origin)\n"
    ]


@pytest.mark.slow  # a command that serves the viewer: seconds to start
def test_malformed_frames_close_their_connection_without_a_traceback(replay):
    """Garbage, bad msgpack, a text frame, unknown and ill-typed messages and out-of-range GUI values: the
    viewer serves on, and its terminal shows no traceback."""
    own = f"http://127.0.0.1:{replay.port}"
    encode = msgspec.msgpack.encode
    slider = next(m["uuid"] for m in asyncio.run(opened(replay.port, own)) if m["type"] == "GuiSliderMessage")
    camera = {
        "type": "ViewerCameraMessage",
        "wxyz": [1.0, 0.0, 0.0, 0.0],
        "position": [3.0, 3.0, 3.0],
        "fov": 1.0,
        "near": 0.01,
        "far": 100.0,
        "image_height": 600,
        "image_width": 800,
        "look_at": [0.0, 0.0, 0.0],
        "up_direction": [0.0, 0.0, 1.0],
    }
    before = len(replay.lines)
    for frame in (
        b"\x00\xffgarbage",
        "a text frame",
        encode([1, 2, 3]),
        encode({"no": "type"}),
        encode({"type": "NoSuchMessage"}),
        encode({"type": "ViewerCameraMessage", "position": "x"}),
    ):
        asyncio.run(opened(replay.port, own, send=[frame]))
    gui = [
        encode(camera),  # the client counts as connected after its first camera message
        *(
            encode({"type": "GuiUpdateMessage", "uuid": slider, "updates": u})
            for u in ({"value": 10**9}, {"value": "x"}, {"value": -5}, {"nosuch": 1})
        ),
        encode({"type": "GuiUpdateMessage", "uuid": "no such element", "updates": {"value": 1}}),
    ]
    asyncio.run(opened(replay.port, own, send=gui))
    with socket.create_connection(("127.0.0.1", replay.port)) as raw:  # not even HTTP
        raw.sendall(b"garbage\r\n\r\n")
        raw.recv(100)
    with pytest.raises(websockets.InvalidStatus) as refused:  # a websocket client, but not viser's
        asyncio.run(handshake(f"ws://127.0.0.1:{replay.port}", origin=own))
    assert refused.value.response.status_code == 400
    time.sleep(1.0)
    assert asyncio.run(opened(replay.port, own))  # still serving
    assert replay.process.poll() is None
    assert replay.lines[before:] == []  # not a line on the terminal
    assert replay.out == ""


@pytest.mark.slow  # a command that serves the viewer: seconds to start
def test_a_host_beyond_this_machine_is_served_with_one_warning_and_its_real_address(run_log):
    served = Served("view", "--replay", str(run_log), "--host", "0.0.0.0", "--port", "0")
    try:
        name = urlsplit(served.url).hostname
        assert name in network_addresses() or name == socket.gethostname(), served.err
        assert name != "0.0.0.0" and not name.startswith("127.")
        warned = [line for line in served.lines if "reachable from the network" in line]
        assert warned == [
            f"besman: warning: the viewer at {served.url} (host 0.0.0.0) is reachable from the network, with "
            "no authentication: anyone who reaches this machine can watch and drive it\n"
        ]
        assert all(served.url in line for line in served.lines if "http://" in line)  # no other address
        # the page as a browser that opened the printed address has it (connected through 127.0.0.1)
        assert asyncio.run(opened(served.port, served.url, host=name))
        with pytest.raises(websockets.InvalidStatus):
            asyncio.run(opened(served.port, "http://evil.example", host=name))
    finally:
        err = served.stop()
    assert "Traceback" not in err and err.count("reachable from the network") == 1


def _not_this_machines() -> str:
    """A documentation address (RFC 5737) that is not this machine's: binding it fails, nothing is sent."""
    for address in ("198.51.100.1", "203.0.113.1", "192.0.2.1"):
        with socket.socket() as probe:
            try:
                probe.bind((address, 0))
            except OSError:
                return address
    pytest.skip("this machine has every documentation address")


@pytest.mark.parametrize(
    "argv",
    [
        ("view", "--replay", "{log}"),
        ("demo", "--view"),
        ("run", str(ROOT / "examples" / "trees" / "grasp_then_place.yaml"), "--view"),
    ],
)
def test_a_host_this_machine_cannot_serve_on_fails_at_once_in_one_line(argv, tmp_path):
    host = _not_this_machines()
    log = tmp_path / "missing.jsonl"  # never read: the host is checked first
    start = time.monotonic()
    result = subprocess.run(
        [sys.executable, "-m", "besman", *(a.format(log=log) for a in argv), "--host", host],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert time.monotonic() - start < 5.0
    assert result.returncode == 2 and result.stdout == ""
    assert result.stderr.startswith(f"besman: error: host {host}: not an address of this machine (")
    assert result.stderr.count("\n") == 1, result.stderr


def test_an_ipv4_address_written_as_ipv6_is_refused_with_its_ipv4_form():
    """viser's server never came up on ``::ffff:127.0.0.1`` (the command hung, silent)."""
    result = subprocess.run(
        [sys.executable, "-m", "besman", "demo", "--view", "--host", "::ffff:127.0.0.1"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2 and result.stdout == ""
    assert result.stderr == (
        "besman: error: host ::ffff:127.0.0.1: an IPv4 address written as IPv6; give it as 127.0.0.1\n"
    )


@pytest.mark.parametrize("allowed", ["*", "null", "viewer.example.org", "https://viewer.example.org/page"])
def test_an_allowed_origin_must_be_one(allowed, tmp_path):
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "besman",
            "view",
            "--replay",
            str(tmp_path / "run.jsonl"),
            "--allow-origin",
            allowed,
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2
    assert result.stderr == (
        f"besman: error: allowed origin {allowed!r}: expected scheme://host[:port], e.g. https://viewer.example.org\n"
    )


@pytest.mark.parametrize(
    ("host", "origin", "accepted"),
    [
        ("127.0.0.1:8080", "http://127.0.0.1:8080", True),
        ("[::1]:8080", "http://[::1]:8080", True),
        ("localhost:9000", "http://localhost:9000", True),  # an SSH tunnel's port on this machine
        ("192.0.2.7:8080", "http://192.0.2.7:8080", True),  # an address of this machine (wildcard host)
        ("localhost", "http://localhost:80", True),  # the default port, written or not
        ("LOCALHOST:8080", "http://localhost:8080", True),
        ("evil.example:8080", "http://evil.example:8080", False),  # someone's name pointed here
        ("127.0.0.1:8080", "http://127.0.0.1:8081", False),
        ("127.0.0.1:8080", "https://127.0.0.1:8080", False),
        ("127.0.0.1:8080", "http://127.0.0.1:8080/page", False),
        ("", "http://127.0.0.1:8080", False),
    ],
)
def test_the_origin_check_accepts_the_page_where_the_browser_found_it(host, origin, accepted):
    """Which Host and Origin headers of a handshake pass :class:`~besman.sim.serving.OriginCheck` (the
    command's tests above open real websockets; these are the cases a client on 127.0.0.1 cannot send)."""
    from websockets.datastructures import Headers

    from besman.sim.serving import OriginCheck

    check = OriginCheck("127.0.0.1", ["https://proxy.example"])
    assert (check.refusal(Headers(Host=host, Origin=origin)) is None) is accepted
    assert check.refusal(Headers(Host=host, Origin="https://proxy.example")) is None
    assert check.refusal(Headers(Host=host)) is None  # no browser
    twice = Headers(Host=host, Origin=origin)
    twice["Origin"] = "http://evil.example"  # a second Origin header: refused, whichever comes first
    assert check.refusal(twice) == "more than one Origin or Host header"
