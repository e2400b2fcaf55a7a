"""The browser viewer: a world mirrored in viser, posed from the simulation, with a behaviour-tree panel.

A :class:`Viewer` serves a web page (viser; 127.0.0.1 unless told otherwise, a free port by default) and
answers websockets only from that page (:mod:`besman.sim.serving`; a host it cannot serve on is an error,
one reachable from the network a warning: :mod:`besman.sim.hosts`). The world's MuJoCo model is mirrored by
mjviser (geoms converted once, moving bodies as batched meshes, poses pushed inside one ``server.atomic()``
per frame), with contacts and frames as toggles in its scene panel.
:meth:`Viewer.show` poses the scene from the simulation; during a run it is called after every tick and
sends a frame whenever waiting for the next tick would leave the browser more than ``MAX_FRAME_GAP`` without
one (at least 30 frames per second of wall time, whatever the run's real-time factor), and always for the
run's last tick. :meth:`Viewer.planar_gizmo` lets people move a task value in the page.
:meth:`Viewer.show_tree` writes the tree panel: every node of the running tree with its status colour and
feedback, indented by depth, the running path, the values that matter (the blackboard's, the active motion)
and the details of a node chosen in the panel's list.
"""

from __future__ import annotations

import contextlib
import html
import io
import math
import time
from collections.abc import Callable, Iterable

import mujoco
from mjviser import ViserMujocoScene

from besman.core.errors import InputError
from besman.sim import hosts, serving
from besman.sim.arm import Arm
from besman.sim.overlays import Overlays

# s of wall time the browser may go without a frame during a run: >= 30 frames per second, with a margin
MAX_FRAME_GAP = 1.0 / 32.0
# What makes Debian's headless Chromium draw viser's WebGL scene whole, in software (tests, benchmarks and
# screenshots drive it through Playwright with these).
HEADLESS_CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
)
NO_NODE = "(choose a node)"
STATUS_COLOURS = {"RUNNING": "#1f77b4", "SUCCESS": "#2ca02c", "FAILURE": "#d62728", "INVALID": "#999999"}


def within(slider) -> float:
    """A viser slider's value, kept within its range (a client may send any number)."""
    value = float(slider.value)
    return min(max(value, slider.min), slider.max) if math.isfinite(value) else slider.min


def headless_chromium(playwright, executable: str = "/usr/bin/chromium"):
    """Debian's Chromium, headless, launched through Playwright (a ``sync_playwright()`` context)."""
    return playwright.chromium.launch(executable_path=executable, args=list(HEADLESS_CHROMIUM_FLAGS))


class Viewer:
    """A viser server showing ``model`` (posed by :meth:`show`) and a tree panel, on ``host`` (this machine
    by default; any other serves the network, with a warning) and ``port``; its websocket answers the served
    page and ``allowed_origins`` (e.g. ``["https://viewer.example.org"]`` for a proxy in front of it)."""

    def __init__(
        self,
        model: mujoco.MjModel,
        *,
        host: str = "127.0.0.1",
        port: int = 0,
        camera_distance: float = 4.0,
        allowed_origins: Iterable[str] = (),
    ) -> None:
        addresses = hosts.host_addresses(host)
        with contextlib.redirect_stdout(io.StringIO()):  # viser's banner: the commands print `url` instead
            self.server = serving.start(host, port, allowed_origins)
        self._url = hosts.url(host, self.server.get_port(), addresses)
        if not hosts.loopback_only(addresses):
            serving.log.warning(
                "besman: warning: the viewer at %s (host %s) is reachable from the network, with no "
                "authentication: anyone who reaches this machine can watch and drive it",
                self._url,
                host,
            )
        self.scene = ViserMujocoScene(self.server, model, num_envs=1)
        # mjviser places every new browser's camera: from the front right, ``camera_distance`` m away
        self.scene.create_scene_gui(camera_distance=camera_distance)
        with self.server.gui.add_folder("Behaviour tree"):
            self._time = self.server.gui.add_markdown("no run yet")
            self._running = self.server.gui.add_markdown("")
            self._tree = self.server.gui.add_html("")
            self._values = self.server.gui.add_html("")
            self._inspect = self.server.gui.add_dropdown("details of", [NO_NODE], initial_value=NO_NODE)
            self._details = self.server.gui.add_markdown("")
        self._inspect.on_update(lambda _: self._show_details())
        self.describe: Callable[[str], str] | None = None  # a node path -> its details (markdown)
        self._overlays: Overlays | None = None
        self._last_frame = self._last_call = -float("inf")

    @property
    def url(self) -> str:
        """The address to open in a browser (for a wildcard host, this machine's first network address)."""
        return self._url

    def show(self, data: mujoco.MjData, *, force: bool = False) -> bool:
        """Poses the scene from ``data`` if a frame is due (or ``force``); returns whether it did.

        A frame is due when waiting for the next call (expected as far off as the last one was) would leave
        the browser more than ``MAX_FRAME_GAP`` without a frame: a run paced at 50 ticks per second shows
        every tick, a fast one about 32 frames per second, whatever the tick rate.
        """
        now = time.perf_counter()
        interval, self._last_call = now - self._last_call, now
        if not force and now - self._last_frame + interval <= MAX_FRAME_GAP:
            return False
        self._last_frame = now
        self.scene.update_from_mjdata(data)
        return True

    def planar_gizmo(
        self,
        name: str,
        position,
        low,
        high,
        *,
        scale: float,
        on_release: Callable[[tuple[float, float]], None],
        status,
    ):
        """A gizmo at ``position`` (x, y, z) that moves in x and y within [``low``, ``high``] (x, y); letting
        go of it calls ``on_release((x, y))``; an :class:`InputError` it raises is shown in ``status``."""
        x, y, z = position
        handle = self.server.scene.add_transform_controls(
            name,
            scale=scale,
            position=(x, y, z),
            disable_rotations=True,
            active_axes=(True, True, False),
            # viser's limits are offsets from where the gizmo was made
            translation_limits=((low[0] - x, high[0] - x), (low[1] - y, high[1] - y), (0.0, 0.0)),
        )

        @handle.on_update
        def _(event) -> None:
            if getattr(event, "phase", "end") != "end":  # dragging: nothing happens before it is let go
                return
            try:
                on_release(tuple(float(v) for v in handle.position[:2]))
            except InputError as error:
                status.content = f"not moved: {error}"

        return handle

    def overlays_for(self, arm: Arm) -> Overlays:
        """The scene's overlays of ``arm``'s motions (made with the first call, then the same)."""
        if self._overlays is None:
            self._overlays = Overlays(self.server, arm)
        return self._overlays

    def set_nodes(self, paths: list[str], describe: Callable[[str], str]) -> None:
        """The nodes the "details of" list offers, and what it shows for one of them."""
        self._inspect.options = [NO_NODE, *paths]
        self.describe = describe

    def show_tree(self, record: dict, paths: list[str], values: dict[str, str] | None = None) -> None:
        """The tree panel for one tick's record (``Runner`` records: statuses, feedback, blackboard): every
        node with its status colour and feedback (the running ones in bold), the running path, ``values``
        (e.g. the blackboard's latest values, the active motion) and the chosen node's details."""
        statuses, rows = record["statuses"], []
        for path in paths:
            status = statuses.get(path, "INVALID")
            depth, name = path.count("/"), html.escape(path.rsplit("/", 1)[-1])
            feedback = record["feedback"].get(path, "")
            rows.append(
                f'<div style="margin-left:{12 * depth}px"><span style="color:{STATUS_COLOURS[status]}">'
                f"&#9679;</span> {f'<b>{name}</b>' if status == 'RUNNING' else name} <small>{status}"
                f"{' - ' + html.escape(feedback) if feedback else ''}</small></div>"
            )
        running = [path for path in paths if statuses.get(path) == "RUNNING"]
        deepest = max(running, key=lambda path: path.count("/"), default=None)
        table = "".join(
            f"<div><code>{html.escape(key)}</code> = {html.escape(value[:120])}</div>"
            for key, value in (values or {}).items()
        )
        self._set(self._time, f"tick {record['tick']}, t = {record['time']:.2f} s")
        self._set(self._running, "running: " + " > ".join(deepest.split("/")) if deepest else "")
        self._set(self._tree, "".join(rows))
        self._set(self._values, table)
        self._show_details()

    def _show_details(self) -> None:
        chosen = self._inspect.value  # a client may send any value, not only one of the options
        shown = chosen != NO_NODE and chosen in self._inspect.options and self.describe
        self._set(self._details, self.describe(chosen) if shown else "")

    @staticmethod
    def _set(handle, content: str) -> None:
        """Sends a panel's content only when it changed (every change is a message to every browser)."""
        if handle.content != content:
            handle.content = content

    def close(self) -> None:
        with contextlib.redirect_stdout(io.StringIO()):  # viser's "(viser) Server stopped": not besman's word
            self.server.stop()
