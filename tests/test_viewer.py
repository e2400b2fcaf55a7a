"""The browser viewer, seen by a real browser: Debian's Chromium, headless, driven by Playwright."""

import io
import shutil
import signal
import subprocess
import threading
from pathlib import Path

import numpy as np
import pytest
from helpers import run_cli, serve_then_interrupt
from PIL import Image

from besman.sim.viewer import MAX_FRAME_GAP, Viewer, headless_chromium
from besman.tasks.running import prepare, run
from besman.trees import grasp_then_place
from besman.trees.watching import Watch

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
WIDTH, HEIGHT = 1280, 800
# x, y (m) and yaw (deg) each, and pick and place's 6 cm box (a seed draws its mass and friction)
CONFIGURATION = {
    "object": (0.55, -0.08, 0.0),
    "place": (0.54, -0.41, 0.0),
    "shape": (0,),
    "size": (0.06,) * 3,
}

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


def unoccluded(model, qpos: np.ndarray, eye: np.ndarray) -> np.ndarray:
    """Which geoms the camera sees at their centre in the pose ``qpos``: a ray from the eye hits the geom
    itself first (a far wheel behind the robot's base is drawn, but not where its centre projects)."""
    import mujoco

    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    seen = np.zeros(model.ngeom, bool)
    hit = np.zeros(1, np.int32)
    for geom, centre in enumerate(data.geom_xpos):
        mujoco.mj_ray(model, data, eye, centre - eye, None, 1, -1, hit)
        seen[geom] = hit[0] == geom
    return seen


def luminance(image: np.ndarray) -> np.ndarray:
    return image[..., :3] @ np.array([0.299, 0.587, 0.114]) / 255.0


def dark_parts_drawn(image: np.ndarray, world, before: np.ndarray, posed, camera, joint: str) -> list[bool]:
    """For each dark part of the robot (wheels, joints, fingers) that stood still between ``before`` and
    ``posed`` (geom positions, body positions, qpos) and that the camera sees: whether the screenshot
    ``image`` is dark there. The empty space above the robot must be the light background."""
    model = world.model
    colour = np.where(
        (model.geom_matid >= 0)[:, None], model.mat_rgba[np.maximum(model.geom_matid, 0)], model.geom_rgba
    )
    root = model.body_rootid[model.jnt_bodyid[model.joint(joint).id]]
    robot = model.body_rootid[model.geom_bodyid] == root
    still = np.linalg.norm(posed[0] - before, axis=1) < 0.01  # where they were drawn
    dark = robot & still & (colour[:, :3] @ [0.299, 0.587, 0.114] < 0.25) & (colour[:, 3] > 0.9)
    dark &= unoccluded(model, posed[2], np.asarray(camera.position))
    pixels = project(posed[0][dark], camera)
    visible = (
        (pixels[:, 0] > 5) & (pixels[:, 0] < WIDTH - 360) & (pixels[:, 1] > 5) & (pixels[:, 1] < HEIGHT - 5)
    )
    assert visible.sum() >= 3
    shade = luminance(image)
    above = posed[1][model.body_rootid == root].copy()
    above[:, 2] = above[:, 2].max() + 0.3  # just above the head: in view of the close camera
    sky = project(above, camera)
    sky = sky[(sky[:, 0] > 5) & (sky[:, 0] < WIDTH - 360) & (sky[:, 1] > 5) & (sky[:, 1] < HEIGHT - 5)]
    background = np.median([shade[int(y), int(x)] for x, y in sky])
    assert len(sky) >= 5 and background > 0.8, "the space above the robot is empty and light"
    return [
        shade[int(y) - 4 : int(y) + 5, int(x) - 4 : int(x) + 5].min() < background - 0.2
        for x, y in pixels[visible]
    ]


@pytest.mark.slow
@needs_chromium
def test_a_running_grasp_then_place_is_seen_in_the_browser_with_its_tree():
    """While the tree runs, the browser draws the robot where it stands: a screenshot every second until the
    scene has faded in (software WebGL, slower on a loaded machine), at most 20 s, all while the run goes."""
    import time

    from playwright.sync_api import sync_playwright

    runner = prepare("pick-place", grasp_then_place(), values=CONFIGURATION, seed=0).runner
    world = runner.executor.world
    viewer = Viewer(world.model)
    runner.observe = Watch(viewer, speed=0.5)  # about 20 s of wall time
    results = []
    run = threading.Thread(target=lambda: results.append(runner.run()))
    joint = runner.executor.arm.joints[0]
    try:
        with sync_playwright() as playwright:
            browser = headless_chromium(playwright, CHROMIUM)
            page = browser.new_page(viewport={"width": WIDTH, "height": HEIGHT})
            page.goto(viewer.url)
            page.wait_for_function("document.body.innerText.includes('Behaviour tree')", timeout=30_000)
            run.start()
            page.wait_for_function("document.body.innerText.includes('RUNNING')", timeout=30_000)
            deadline = time.monotonic() + 20
            while True:
                page.wait_for_timeout(1000)
                assert run.is_alive(), "the screenshot is taken while the tree runs"
                before = world.data.geom_xpos.copy()
                image = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB"))
                # The drawn frame lies between these two poses.
                posed = world.data.geom_xpos.copy(), world.data.xpos.copy(), world.data.qpos.copy()
                (client,) = viewer.server.get_clients().values()
                hits = dark_parts_drawn(image, world, before, posed, client.camera, joint)
                if np.mean(hits) > 0.6 or time.monotonic() > deadline:
                    break
            run.join(timeout=120)
            page.wait_for_function("document.body.innerText.includes('succeeded')", timeout=30_000)
            browser.close()
    finally:
        viewer.close()
    assert results and results[0].status == "SUCCESS"
    assert image.std() > 10, "not a blank page"
    assert np.mean(hits) > 0.6, f"{sum(hits)} of {len(hits)} dark robot parts drawn dark"


@pytest.mark.slow
def test_demo_view_serves_on_localhost_until_interrupted(tmp_path):
    """``besman demo --view`` prints the URL, runs (writing its log), keeps serving the page, and ends on
    Ctrl-C as every command does (exit 130, ``besman: interrupted``; checked by ``serve_then_interrupt``)."""
    import sys

    from besman.trees.runner import read_log

    log = tmp_path / "run.jsonl"
    argv = [sys.executable, "-m", "besman", "demo", "--view", "--port", "0", "--speed", "20", "--log", log]
    out, _ = serve_then_interrupt(argv)
    assert out.splitlines()[1].startswith("SUCCESS: placement error")
    assert read_log(log)[2]["status"] == "SUCCESS"


@pytest.mark.slow  # a command that serves the viewer: seconds to start
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
def test_view_replay_ends_as_every_command_on_ctrl_c_and_sigterm(tmp_path, signum):
    """``besman view --replay`` serves until stopped, then ends as every command does: exit 130 after Ctrl-C
    and 143 after SIGTERM, one line (``besman: interrupted`` / ``besman: terminated``), no traceback and no
    viser "Server stopped" (:func:`helpers.serve_then_interrupt` checks them)."""
    import sys

    log = tmp_path / "run.jsonl"
    subprocess.run([sys.executable, "-m", "besman", "demo", "--log", log], check=True, capture_output=True)
    argv = [sys.executable, "-m", "besman", "view", "--replay", log, "--port", "0"]
    out, err = serve_then_interrupt(argv, signum=signum)
    assert out == ""
    served, stopped = err.splitlines()[-2:]  # nothing between the viewer's address and the one line
    assert served.startswith("the viewer stays at http://127.0.0.1:") and served.endswith(" until Ctrl-C"), (
        err
    )
    assert stopped == ("besman: terminated" if signum == signal.SIGTERM else "besman: interrupted"), err


def test_the_viewer_binds_this_machine_by_default():
    from besman.sim.world import tabletop_world

    viewer = Viewer(tabletop_world().model)
    try:
        assert viewer.server.get_host() == "127.0.0.1" and viewer.url.startswith("http://127.0.0.1:")
    finally:
        viewer.close()


@pytest.mark.parametrize("call_interval", [0.020, 0.013, 0.001])  # ticks at speed 1, about 1.5 and unpaced
def test_frames_come_at_least_30_times_a_second_whatever_the_tick_rate(call_interval):
    import time

    from besman.sim.world import tabletop_world

    world = tabletop_world()
    viewer = Viewer(world.model)
    frames, deadline = [], time.perf_counter() + 0.6
    try:
        while time.perf_counter() < deadline:
            if viewer.show(world.data):
                frames.append(time.perf_counter())
            time.sleep(call_interval)
    finally:
        viewer.close()
    gaps = np.diff(frames)
    assert np.median(gaps) <= 1 / 30, f"median gap {np.median(gaps):.3f} s"
    if call_interval < MAX_FRAME_GAP / 2:  # several calls per frame are due: not a frame with each
        assert np.median(gaps) >= MAX_FRAME_GAP / 2


@pytest.mark.slow
@needs_chromium
def test_a_logged_run_replays_scene_and_tree_on_one_timeline(tmp_path):
    """``besman view --replay``: the slider picks a tick; the scene takes that tick's logged pose and the tree
    panel its statuses, in the browser too; "play" advances the timeline."""
    import time

    from playwright.sync_api import sync_playwright

    from besman.tasks.running import executor_of
    from besman.trees.watching import Replay

    log = tmp_path / "run.jsonl"
    run("pick-place", grasp_then_place(), values=CONFIGURATION, log=log)
    replay = Replay(log, executor_of, {"port": 0})
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


def test_view_throw_refuses_a_missing_template_and_a_bad_target_before_serving(tmp_path, capsys):

    pool = str(Path(__file__).parents[1] / "examples/pools/throwing")
    code, _, err = run_cli(capsys, "view", "--throw", str(tmp_path), "--port", "0")
    assert code == 2 and "no template 'throw' (it has: none)" in err
    code, _, err = run_cli(capsys, "view", "--throw", pool, "--target", "a,b", "--port", "0")
    assert code == 2 and "--target 'a,b': expected two numbers" in err
    code, _, err = run_cli(capsys, "view", "--throw", pool, "--target", "0,0", "--port", "0")
    assert code == 2 and "x = 0 is outside the task's bounds [-7, -1]" in err
    with pytest.raises(SystemExit) as exit:
        run_cli(capsys, "view", "--replay", "run.jsonl", "--throw", pool)
    assert exit.value.code == 2 and "not allowed with argument" in capsys.readouterr().err


def test_a_replay_of_a_missing_or_foreign_log_is_one_clear_error(tmp_path, capsys):

    code, _, err = run_cli(capsys, "view", "--replay", str(tmp_path / "none.jsonl"))
    assert code == 2 and "none.jsonl: no such file" in err
    (tmp_path / "other.jsonl").write_text('{"kind": "something else"}\n')
    code, _, err = run_cli(capsys, "view", "--replay", str(tmp_path / "other.jsonl"))
    assert code == 2 and "not a besman run log" in err


def wait_until(condition, seconds: float = 30.0) -> bool:
    import time

    deadline = time.monotonic() + seconds
    while not condition() and time.monotonic() < deadline:
        time.sleep(0.05)
    return condition()


def drag(page, session, name: str, dx: float) -> None:
    """Drags the x arrow of a task gizmo by ``dx`` metres with the mouse, as a user would."""
    (client,) = session.viewer.server.get_clients().values()
    origin = np.asarray(session.gizmos[name].position)
    start, end = project(np.array([origin + [0.1, 0.0, 0.0], origin + [0.1 + dx, 0.0, 0.0]]), client.camera)
    page.mouse.move(*start)
    page.mouse.down()
    for k in range(1, 11):
        page.mouse.move(*(start + (end - start) * k / 10))
        page.wait_for_timeout(50)
    page.mouse.up()


@pytest.mark.slow
@needs_chromium
def test_the_browser_runs_pauses_breaks_and_moves_the_task():
    """Run clicked in the page: the simulation advances and the tree panel shows RUNNING, then SUCCESS; a
    breakpoint pauses the run where its node is ticked; Step runs one tick; the object's gizmo dragged with
    the mouse sets tau, and the next run grasps the box at its new place."""
    import re

    from playwright.sync_api import sync_playwright

    from besman.tasks.session import Session

    session = Session(
        grasp_then_place(),
        {"object": (0.55, -0.08, 30.0), "place": (0.54, -0.41, 0.0)},
        task="pick-place",
        speed=2.0,
        viewer_options={"port": 0},
    )
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
            assert wait_until(lambda: len(session.runner.records) == ticks + 1 and session.paused, 10)
            session.breakpoint.value = "(none)"
            page.wait_for_timeout(2000)  # the paused scene, drawn whole
            drag(page, session, "object", -0.06)
            assert wait_until(lambda: session.values["object"][0] < 0.53, 10), session.state.content
            moved = session.values["object"]
            assert moved[2] == 30.0, "dragged in x and y: the yaw stays"
            page.get_by_role(
                "button", name="Run", exact=True
            ).click()  # the paused run gives way to a new one
            page.wait_for_function("document.body.innerText.includes('SUCCESS: succeeded')", timeout=60_000)
            browser.close()
        assert session.result.status == "SUCCESS"
        judged = session.judge(session.result)  # the task's rule, at the dragged object's run
        assert judged.success and judged.task == "pick-place"
        np.testing.assert_allclose(judged.settings["object"], moved, atol=1e-6)
        perceived = next(
            message
            for record in session.runner.records
            for path, message in record["feedback"].items()
            if path.endswith("/perceive")
        )
        x, y = map(float, re.match(r"box at \[([-\d.]+), ([-\d.]+),", perceived).groups())
        assert abs(x - moved[0]) < 0.005 and abs(y - moved[1]) < 0.005, "grasped where it was dragged to"
    finally:
        session.close()


@pytest.mark.slow
@needs_chromium
def test_two_browsers_see_one_run_and_one_may_leave():
    """Two pages watch one run; one closes mid-run; the run goes on undisturbed (the same ticks and statuses
    as the same run unwatched) and the other page sees it end, showing the server's last tick."""
    from playwright.sync_api import sync_playwright

    from besman.tasks.session import Session
    from besman.trees.runner import statuses

    values = CONFIGURATION
    unwatched = prepare("pick-place", grasp_then_place(), values=values).runner
    unwatched.run()
    # at half speed the run (about 10 s of simulation) outlasts the pages' steps on a loaded machine
    session = Session(grasp_then_place(), values, task="pick-place", speed=0.5, viewer_options={"port": 0})
    try:
        with sync_playwright() as playwright:
            browser = headless_chromium(playwright, CHROMIUM)
            pages = [browser.new_context().new_page() for _ in range(2)]
            for page in pages:
                page.goto(session.viewer.url)
                page.wait_for_function("document.body.innerText.includes('Behaviour tree')", timeout=30_000)
            assert wait_until(lambda: len(session.viewer.server.get_clients()) == 2)
            session.run()
            for page in pages:
                page.wait_for_function("document.body.innerText.includes('RUNNING')", timeout=30_000)
            pages[0].context.close()  # leaves mid-run
            assert wait_until(lambda: len(session.viewer.server.get_clients()) == 1)
            assert session.result is None, "the run was still going when the page left"
            pages[1].wait_for_function(
                "document.body.innerText.includes('SUCCESS: succeeded')", timeout=60_000
            )
            last = session.runner.records[-1]
            assert f"tick {last['tick']}, t = {last['time']:.2f} s" in pages[1].inner_text("body")
            browser.close()
        assert list(statuses(session.runner.records)) == list(statuses(unwatched.records))
    finally:
        session.close()


def _mesh_extent(session, node: str) -> np.ndarray:
    """The half extents (x, y, z) of the mesh the page is sent for a scene node."""
    import trimesh

    glb = session.viewer.server.scene._handle_from_node_name[node]._impl.props.glb_data
    low, high = trimesh.load(io.BytesIO(glb), file_type="glb", force="mesh").bounds
    return (high - low) / 2


def test_the_session_drags_x_and_y_keeps_the_yaw_and_shows_the_object_as_it_is():
    """Server side, no browser: pick-place's object and place are x, y and yaw; their gizmos stand at x, y on
    their surfaces and the target ring at the place's; letting go of a gizmo sets x and y and keeps the yaw
    (a value the run would refuse is refused by name, and shown); a shape and size set for the next run
    rebuild the page's object as it is, a cylinder of that diameter and height, standing at the yaw."""
    import mujoco

    from besman.core.errors import InputError
    from besman.sim.objects import yaw_of
    from besman.tasks.session import Session

    def ring() -> np.ndarray:
        points = session.viewer.server.scene._handle_from_node_name["/overlays/place"]._impl.props.points
        return points.reshape(-1, 3).mean(axis=0)

    session = Session(
        grasp_then_place(),
        {"object": (0.55, -0.08, 30.0), "place": (0.54, -0.41, -45.0)},
        task="pick-place",
        viewer_options={"port": 0},
    )
    try:
        table, shelf = session.surfaces["object"], session.surfaces["place"]
        np.testing.assert_allclose(session.gizmos["object"].position, (0.55, -0.08, table))
        np.testing.assert_allclose(session.gizmos["place"].position, (0.54, -0.41, shelf))
        np.testing.assert_allclose(ring()[:2], (0.54, -0.41), atol=1e-6)
        np.testing.assert_allclose(_mesh_extent(session, "/bodies/box/group0"), (0.03, 0.03, 0.03), atol=1e-4)
        session.set_value("object", (0.5, -0.05))  # what letting go of its gizmo does
        session.set_value("place", (0.5, -0.4))
        assert session.values["object"] == (0.5, -0.05, 30.0)
        assert session.values["place"] == (0.5, -0.4, -45.0)
        np.testing.assert_allclose(session.gizmos["object"].position, (0.5, -0.05, table))
        np.testing.assert_allclose(ring()[:2], (0.5, -0.4), atol=1e-6)
        with pytest.raises(InputError, match=r"tau object_x = 0\.9 is outside the task's bounds"):
            session.set_value("object", (0.9, -0.05))
        with pytest.raises(InputError, match="'sphere' is not one of box, cylinder"):
            session.set_value("shape", "sphere")
        assert session.values["object"] == (0.5, -0.05, 30.0) and session.values["shape"] == (0.0,)
        session.set_value("shape", "cylinder")
        session.set_value("size", (0.05, 0.04, 0.07))  # a cylinder's depth is its diameter
        assert session.values["shape"] == (1.0,) and session.values["size"] == (0.05, 0.05, 0.07)
        session.reset()  # what Run does next, for the values set
        world = session.runner.executor.world
        assert session.runner.run_info["values"]["object"] == [0.5, -0.05, 30.0]
        shown = session.viewer.scene.mj_model.geom("box")
        assert world.model.geom("box").type == shown.type == mujoco.mjtGeom.mjGEOM_CYLINDER
        np.testing.assert_allclose(shown.size, world.model.geom("box").size)
        np.testing.assert_allclose(
            _mesh_extent(session, "/bodies/box/group0"), (0.025, 0.025, 0.035), atol=1e-4
        )
        pose = world.object_pose("box")
        assert np.degrees(yaw_of(pose.rotation)) == pytest.approx(30.0, abs=1e-6)
    finally:
        session.close()


def test_overlays_and_the_tree_panel_follow_a_template_run():
    """Server side, no browser: a tree that instantiates a skill template and executes the instance. The
    overlays show the instance's planned hand path (ending where the hand ends), the executed path, the
    target frame at the hand's final pose and the template's spread (16 seeded samples, wider where the
    template is unsure); the panel shows the blackboard's tau and a node's details."""
    import py_trees

    from besman.sim.executor import Executor
    from besman.sim.manipulation import plan_pick
    from besman.sim.plans import PickPlacePlan
    from besman.sim.world import tabletop_world
    from besman.skills.task_bounds import TaskBounds
    from besman.skills.template import SkillTemplate
    from besman.trees.leaves import ExecutePrimitive, InstantiateSkillTemplate
    from besman.trees.runner import Runner

    runner = prepare("pick-place", grasp_then_place(), values=CONFIGURATION, seed=0).runner
    arm, box = runner.executor.arm, runner.executor.world.objects["box"]
    taus = np.array([[0.5, -0.12], [0.6, -0.12], [0.5, 0.0], [0.6, 0.0]])
    reaches = [plan_pick(arm, arm.measured().copy(), box, tau, PickPlacePlan()).reach for tau in taus]
    template = SkillTemplate(
        "reach",
        reaches[0],
        taus,
        [p.theta for p in reaches],
        TaskBounds(("x", "y"), (0.45, -0.2), (0.65, 0.05)),
        prior_spread=0.1,
    )
    root = py_trees.composites.Sequence(
        "reach",
        memory=True,
        children=[InstantiateSkillTemplate("instantiate", template=template), ExecutePrimitive("execute")],
    )
    py_trees.blackboard.Blackboard.clear()
    py_trees.blackboard.Blackboard.set("/tau", np.array([0.55, -0.06]))
    runner = Runner(root, Executor(tabletop_world()))
    viewer = Viewer(runner.executor.world.model)
    try:
        runner.observe = Watch(viewer, speed=float("inf"))
        assert runner.run().status == "SUCCESS"
        overlays = viewer.overlays_for(arm)
        handles = {handle.name: handle for kind in overlays._handles.values() for handle in kind}
        hand = runner.executor.world.data.site(arm.site).xpos
        np.testing.assert_allclose(handles["/overlays/target"].position, hand, atol=0.01)
        scene = viewer.server.scene._handle_from_node_name
        planned = scene["/overlays/planned"]._impl.props.points
        executed = scene["/overlays/executed"]._impl.props.points
        assert np.linalg.norm(planned[-1, 1] - hand) < 0.01 and np.linalg.norm(executed[-1, 1] - hand) < 0.02
        spread = scene["/overlays/spread"]._impl.props.points.reshape(16, -1, 2, 3)
        ends = spread[:, -1, 1]
        assert 0.001 < ends.std(axis=0).max() < 0.2, "a fan of distinct paths around the instance"
        viewer._inspect.value = "reach/instantiate"
        assert (
            "InstantiateSkillTemplate" in viewer._details.content
            and "`/tau` (read)" in viewer._details.content
        )
        assert "/tau" in viewer._values.content and "active motion" in viewer._values.content
    finally:
        viewer.close()


def test_a_throwing_template_shows_its_spread_and_where_the_ball_lands():
    """``besman view --throw``'s view of the committed pool: the landing it reports is the task's own
    evaluation of the template's mean, the drawn flight ends there, the spread holds 16 distinct hand paths
    ending where the mean's does on average, and a target outside the task box is refused by name."""
    from pathlib import Path

    from besman.core.errors import InputError
    from besman.skills.pool import SkillTemplatePool
    from besman.tasks.throwing.view import ThrowingView

    template = SkillTemplatePool(Path(__file__).parents[1] / "examples/pools/throwing")["throw"]
    target = (-4.0, -2.0)
    view = ThrowingView(template, target, {"port": 0})
    try:
        view.throw(speed=50.0)
        (detail,) = view.task.evaluate(
            template.predict(np.array(target))[0][None], np.array([target])
        ).details
        np.testing.assert_allclose(view.landing, detail.landing, atol=1e-9)
        scene = view.viewer.server.scene._handle_from_node_name
        flight = scene["/throw/flight"]._impl.props.points
        radius = view.task.ball_radius
        assert np.linalg.norm(flight[-1, 1, :2] - view.landing) < 0.3 and flight[-1, 1, 2] < 3 * radius
        spread = scene["/throw/spread"]._impl.props.points.reshape(16, -1, 2, 3)[:, -1, 1]
        planned = scene["/throw/planned"]._impl.props.points[-1, 1]
        assert spread.std(axis=0).max() > 1e-3 and np.linalg.norm(spread.mean(axis=0) - planned) < 0.2
        assert f"{np.linalg.norm(np.subtract(view.landing, target)):.2f} m away" in view.status.content
        with pytest.raises(InputError, match="outside the task's bounds"):
            view.throw((0.0, 0.0))
    finally:
        view.close()


def test_a_ctrl_c_while_a_session_runs_stops_its_run_before_its_viewer(recwarn):
    """Ctrl-C while ``Session.start`` waits for the run (``besman demo --view``): closing the session stops
    the run's thread, then the viewer, so nothing is sent to a stopped viewer and no thread runs the tree on.
    Python 3.11 marks a thread whose join a Ctrl-C interrupted as ended while it runs on (CPython gh-90882):
    a session that waited with join closed the viewer under the running tree."""
    from besman.tasks.session import Session

    session = Session(grasp_then_place(), task="pick-place", viewer_options={"port": 0})
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)  # as in a command (not xdist's)
    try:
        threading.Timer(1.0, signal.pthread_kill, (threading.main_thread().ident, signal.SIGINT)).start()
        with pytest.raises(KeyboardInterrupt):
            session.start()  # a run of about 10 s of simulation, at real time
    finally:
        signal.signal(signal.SIGINT, previous)
        session.close()
    running = lambda: any(thread.name.endswith("(_run)") for thread in threading.enumerate())  # noqa: E731
    assert wait_until(lambda: not running(), 1.0)  # the run's thread sets its event, then ends
    assert [str(warning.message) for warning in recwarn if "closed connection" in str(warning.message)] == []
    session.run()  # the page's Run after the close starts nothing
    assert not running()


def test_a_reset_from_the_page_during_the_commands_run_makes_it_wait_for_the_next_run():
    """``besman demo --view``: the page's Reset while the command waits for its run abandons that run; the
    command then waits for the run the page's Run starts, and reports that one."""
    from besman.tasks.session import Session

    session = Session(grasp_then_place(), task="pick-place", speed=4.0, viewer_options={"port": 0})
    try:
        threading.Timer(0.5, session.reset).start()
        threading.Timer(1.5, session.run).start()
        result = session.start()
    finally:
        session.close()
    assert result.status == "SUCCESS" and result.sim_time_s > 5.0  # the whole second run, from its start
