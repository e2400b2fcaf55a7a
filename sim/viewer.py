"""The browser viewer: a world mirrored in viser, posed from the simulation, with a behaviour-tree panel.

A :class:`Viewer` serves a web page (viser; 127.0.0.1 unless told otherwise, a free port by default). The
world's MuJoCo model is mirrored by mjviser (geoms converted once, moving bodies as batched meshes, poses
pushed inside one ``server.atomic()`` per frame), with contacts and frames as toggles in its scene panel.
:meth:`Viewer.show` poses the scene from the simulation; during a run it is called after every tick and
sends a frame whenever 1/60 s of wall time has passed since the last one (at least 30 frames per second of
wall time, whatever the run's real-time factor) and always for the run's last tick. :meth:`Viewer.show_tree`
writes the tree panel: every node of the running tree with its status colour and feedback, indented by
depth, and the blackboard values written that tick.
"""

from __future__ import annotations

import contextlib
import html
import sys
import time

import mujoco
import viser
from mjviser import ViserMujocoScene

FRAME_PERIOD = 1.0 / 60.0  # s of wall time between frames during a run
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
STATUS_COLOURS = {"RUNNING": "#1f77b4", "SUCCESS": "#2ca02c", "FAILURE": "#d62728", "INVALID": "#999999"}


def headless_chromium(playwright, executable: str = "/usr/bin/chromium"):
    """Debian's Chromium, headless, launched through Playwright (a ``sync_playwright()`` context)."""
    return playwright.chromium.launch(executable_path=executable, args=list(HEADLESS_CHROMIUM_FLAGS))


class Viewer:
    """A viser server showing ``model`` (posed by :meth:`show`) and a tree panel."""

    def __init__(self, model: mujoco.MjModel, *, host: str = "127.0.0.1", port: int = 0) -> None:
        with contextlib.redirect_stdout(sys.stderr):  # viser's banner; stdout is for the command's output
            self.server = viser.ViserServer(host=host, port=port, verbose=False)
        self.scene = ViserMujocoScene(self.server, model, num_envs=1)
        self.scene.create_scene_gui()
        self.server.initial_camera.position = (2.2, -1.6, 1.9)  # in front of AILA, looking at the table
        self.server.initial_camera.look_at = (0.4, -0.2, 0.9)
        with self.server.gui.add_folder("Behaviour tree"):
            self._time = self.server.gui.add_markdown("no run yet")
            self._tree = self.server.gui.add_html("")
        self._last_frame = -float("inf")

    @property
    def url(self) -> str:
        host = self.server.get_host()
        return f"http://{'127.0.0.1' if host in ('0.0.0.0', '') else host}:{self.server.get_port()}"

    def show(self, data: mujoco.MjData, *, force: bool = False) -> bool:
        """Poses the scene from ``data`` if a frame is due (or ``force``); returns whether it did."""
        now = time.perf_counter()
        if not force and now - self._last_frame < FRAME_PERIOD:
            return False
        self._last_frame = now
        self.scene.update_from_mjdata(data)
        return True

    def show_tree(self, record: dict, paths: list[str]) -> None:
        """The tree panel for one tick's record (``Runner`` records: statuses, feedback, blackboard)."""
        rows = []
        for path in paths:
            status = record["statuses"].get(path, "INVALID")
            depth, name = path.count("/"), path.rsplit("/", 1)[-1]
            feedback = record["feedback"].get(path, "")
            rows.append(
                f'<div style="margin-left:{12 * depth}px"><span style="color:{STATUS_COLOURS[status]}">'
                f"&#9679;</span> {html.escape(name)} <small>{status}"
                f"{' - ' + html.escape(feedback) if feedback else ''}</small></div>"
            )
        writes = "".join(
            f"<div><code>{html.escape(change['key'])}</code> = {html.escape(str(change['value'])[:80])}</div>"
            for change in record["blackboard"]
        )
        self._time.content = f"tick {record['tick']}, t = {record['time']:.2f} s"
        self._tree.content = "".join(rows) + (f"<hr/>{writes}" if writes else "")

    def close(self) -> None:
        with contextlib.redirect_stdout(sys.stderr):
            self.server.stop()
