"""The browser viewer, seen by a real browser: Debian's Chromium, headless, driven by Playwright."""

import io
import shutil
import threading

import numpy as np
import pytest
from PIL import Image

from besman.sim.viewer import Viewer, headless_chromium
from besman.trees import grasp_then_place
from besman.trees.tabletop import tabletop_run
from besman.trees.watching import Watch

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
WIDTH, HEIGHT = 1280, 800

needs_chromium = pytest.mark.skipif(
    shutil.which("chromium") is None, reason="needs Debian's chromium (apt-get install chromium)"
)


def project(points: np.ndarray, camera) -> np.ndarray:
    """Pixels (x right, y down) of world points in the browser's camera (three.js: a vertical fov)."""
    forward = np.asarray(camera.look_at) - np.asarray(camera.position)
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, np.asarray(camera.up_direction))
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    offsets = points - np.asarray(camera.position)
    depth = offsets @ forward
    scale = np.tan(camera.fov / 2) * depth
    x = (offsets @ right) / (scale * camera.aspect)
    y = (offsets @ up) / scale
    return np.column_stack([(x + 1) / 2 * WIDTH, (1 - y) / 2 * HEIGHT])


def luminance(image: np.ndarray) -> np.ndarray:
    return image[..., :3] @ np.array([0.299, 0.587, 0.114]) / 255.0


@pytest.mark.slow
@needs_chromium
def test_a_running_grasp_then_place_is_seen_in_the_browser_with_its_tree():
    from playwright.sync_api import sync_playwright

    runner, _ = tabletop_run(grasp_then_place(), {"object": (0.55, -0.08), "place": (0.54, -0.41)}, seed=0)
    world = runner.executor.world
    viewer = Viewer(world.model)
    runner.observe = Watch(viewer, speed=1.0)  # about 10 s of wall time
    results = []
    run = threading.Thread(target=lambda: results.append(runner.run()))
    try:
        with sync_playwright() as playwright:
            browser = headless_chromium(playwright, CHROMIUM)
            page = browser.new_page(viewport={"width": WIDTH, "height": HEIGHT})
            page.goto(viewer.url)
            page.wait_for_function("document.body.innerText.includes('Behaviour tree')", timeout=30_000)
            run.start()
            page.wait_for_function("document.body.innerText.includes('RUNNING')", timeout=30_000)
            page.wait_for_timeout(1500)  # software WebGL: let a few frames land
            assert run.is_alive(), "the screenshot is taken while the tree runs"
            before = world.data.geom_xpos.copy()
            image = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB"))
            # The drawn frame lies between these two poses: parts that stood still are where they were drawn.
            posed = world.data.geom_xpos.copy(), world.data.xpos.copy()
            still = np.linalg.norm(posed[0] - before, axis=1) < 0.01
            (client,) = viewer.server.get_clients().values()
            camera = client.camera
            run.join(timeout=60)
            page.wait_for_function("document.body.innerText.includes('succeeded')", timeout=30_000)
            browser.close()
    finally:
        viewer.close()
    assert results and results[0].status == "SUCCESS"
    assert image.std() > 10, "not a blank page"
    # The robot's dark parts (wheels, joints, fingers) where the camera sees them: dark pixels; the empty
    # space above the robot: the light background.
    model = world.model
    colour = np.where(
        (model.geom_matid >= 0)[:, None], model.mat_rgba[np.maximum(model.geom_matid, 0)], model.geom_rgba
    )
    root = model.body_rootid[model.jnt_bodyid[model.joint(runner.executor.arm.joints[0]).id]]
    robot = model.body_rootid[model.geom_bodyid] == root
    dark = robot & still & (colour[:, :3] @ [0.299, 0.587, 0.114] < 0.25) & (colour[:, 3] > 0.9)
    pixels = project(posed[0][dark], camera)
    visible = (
        (pixels[:, 0] > 5) & (pixels[:, 0] < WIDTH - 360) & (pixels[:, 1] > 5) & (pixels[:, 1] < HEIGHT - 5)
    )
    assert visible.sum() >= 5
    shade = luminance(image)

    def darkest_near(x, y):
        return shade[int(y) - 4 : int(y) + 5, int(x) - 4 : int(x) + 5].min()

    sky = project(posed[1][model.body_rootid == root] + [0.0, 0.0, 1.5], camera)
    sky = sky[(sky[:, 0] > 5) & (sky[:, 0] < WIDTH - 360) & (sky[:, 1] > 5) & (sky[:, 1] < HEIGHT - 5)]
    background = np.median([shade[int(y), int(x)] for x, y in sky])
    assert len(sky) >= 5 and background > 0.8, "the space above the robot is empty and light"
    hits = [darkest_near(x, y) < background - 0.2 for x, y in pixels[visible]]
    assert np.mean(hits) > 0.6, f"{sum(hits)} of {len(hits)} dark robot parts drawn dark"


@pytest.mark.slow
def test_demo_view_serves_on_localhost_until_interrupted():
    """``besman demo --view`` prints the URL, runs, keeps serving the page, and ends cleanly on Ctrl-C."""
    import re
    import signal
    import subprocess
    import sys
    import time
    import urllib.request

    process = subprocess.Popen(
        [sys.executable, "-m", "besman", "demo", "--view", "--port", "0", "--speed", "20"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        lines = []
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not any("viewer stays" in line for line in lines):
            lines.append(process.stderr.readline())
        url = re.search(r"http://127\.0\.0\.1:\d+", "".join(lines)).group(0)  # bound to this machine
        with urllib.request.urlopen(url, timeout=10) as response:
            assert response.status == 200 and b"<html" in response.read().lower()
    finally:
        process.send_signal(signal.SIGINT)
        out, _ = process.communicate(timeout=30)
    assert process.returncode == 0 and out.splitlines()[1].startswith("SUCCESS: placement error")


def test_the_viewer_binds_this_machine_by_default():
    from besman.sim.world import tabletop_world

    viewer = Viewer(tabletop_world().model)
    try:
        assert viewer.server.get_host() == "127.0.0.1" and viewer.url.startswith("http://127.0.0.1:")
    finally:
        viewer.close()


@pytest.mark.slow
@needs_chromium
def test_a_logged_run_replays_scene_and_tree_on_one_timeline(tmp_path):
    """``besman view --replay``: the slider picks a tick; the scene takes that tick's logged pose and the tree
    panel its statuses, in the browser too; "play" advances the timeline."""
    import time

    from playwright.sync_api import sync_playwright

    from besman.trees.tabletop import run_on_tabletop
    from besman.trees.watching import Replay

    log = tmp_path / "run.jsonl"
    run_on_tabletop(grasp_then_place(), {"object": (0.55, -0.08), "place": (0.54, -0.41)}, log=log)
    replay = Replay(log, {"port": 0})
    try:
        middle = len(replay.records) // 2
        replay.slider.value = middle
        time.sleep(0.5)
        record = replay.records[middle]
        arm = replay.world.data.qpos[replay._arm]
        np.testing.assert_allclose(arm, record["robot"]["joints"], atol=1e-5)
        box = replay.world.data.qpos[replay._objects["box"] : replay._objects["box"] + 3]
        np.testing.assert_allclose(box, record["robot"]["objects"]["box"][:3], atol=1e-5)
        with sync_playwright() as playwright:
            browser = headless_chromium(playwright, CHROMIUM)
            page = browser.new_page(viewport={"width": WIDTH, "height": HEIGHT})
            page.goto(replay.viewer.url)
            page.wait_for_function(f"document.body.innerText.includes('tick {middle},')", timeout=30_000)
            running = [
                path.rsplit("/", 1)[-1] for path, status in record["statuses"].items() if status == "RUNNING"
            ]
            assert running and all(name in page.inner_text("body") for name in running)
            replay.play.value = True
            page.wait_for_function(f"!document.body.innerText.includes('tick {middle},')", timeout=30_000)
            browser.close()
        assert int(replay.slider.value) != middle
    finally:
        replay.close()


def test_a_replay_of_a_missing_or_foreign_log_is_one_clear_error(tmp_path, capsys):
    from tests.helpers import run_cli

    code, _, err = run_cli(capsys, "view", "--replay", str(tmp_path / "none.jsonl"))
    assert code == 2 and "none.jsonl: no such file" in err
    (tmp_path / "other.jsonl").write_text('{"kind": "something else"}\n')
    code, _, err = run_cli(capsys, "view", "--replay", str(tmp_path / "other.jsonl"))
    assert code == 2 and "not a besman run log" in err


@pytest.mark.slow
@needs_chromium
def test_the_browser_runs_pauses_breaks_and_moves_the_task():
    """Run clicked in the page: the simulation advances and the tree panel shows RUNNING, then SUCCESS; a
    breakpoint pauses the run where its node is ticked; Step runs one tick; moving the object's gizmo sets
    tau, and the next run grasps the box at its new place."""
    import time

    from playwright.sync_api import sync_playwright

    from besman.trees.session import Session

    session = Session(grasp_then_place(), {"object": (0.55, -0.08), "place": (0.54, -0.41)}, {"port": 0})
    session.speed.value = 2.0  # about 5 s: long enough to see it running
    try:
        with sync_playwright() as playwright:
            browser = headless_chromium(playwright, CHROMIUM)
            page = browser.new_page(viewport={"width": WIDTH, "height": HEIGHT})
            page.goto(session.viewer.url)
            page.wait_for_function("document.body.innerText.includes('Behaviour tree')", timeout=30_000)
            page.get_by_role("button", name="Run", exact=True).click()
            page.wait_for_function("document.body.innerText.includes('RUNNING')", timeout=30_000)
            assert session.runner.executor.time > 0
            page.wait_for_function("document.body.innerText.includes('SUCCESS: succeeded')", timeout=60_000)
            assert session.result.status == "SUCCESS" and session.runner.executor.time > 5.0
            plan_place = next(path for path in session.runner.paths.values() if path.endswith("/plan place"))
            session.breakpoint.value = plan_place
            session.speed.value = 10.0
            page.get_by_role("button", name="Run", exact=True).click()  # a new run
            page.wait_for_function(
                "document.body.innerText.includes('paused at the breakpoint')", timeout=60_000
            )
            ticks = len(session.runner.records)
            assert session.paused and plan_place in session.runner.records[-1]["statuses"]
            page.get_by_role("button", name="Step", exact=True).click()
            deadline = time.monotonic() + 10
            while (
                len(session.runner.records) == ticks or not session.paused
            ) and time.monotonic() < deadline:
                time.sleep(0.05)
            assert len(session.runner.records) == ticks + 1 and session.paused
            browser.close()
        session.breakpoint.value = "(none)"
        session.gizmos["object"].position = (0.5, -0.05, session.gizmos["object"].position[2])
        session.set_value("object", session.gizmos["object"].position[:2])  # what letting go of it does
        session.reset()  # the paused run ends; the next one uses the new tau
        session.run()
        deadline = time.monotonic() + 60
        while session.result is None and time.monotonic() < deadline:
            time.sleep(0.1)
        assert session.result.status == "SUCCESS"
        messages = [message for record in session.runner.records for message in record["feedback"].values()]
        assert any(message.startswith("box at [0.5, -0.05,") for message in messages), (
            "perceived where it was moved"
        )
    finally:
        session.close()
