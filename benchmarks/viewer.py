"""What the browser viewer costs: one scene update for AILA, and grasp-then-place with and without a viewer.

    python benchmarks/viewer.py [--json] [--runs 7]

In one run: the server-side time of one update of the mirrored AILA scene (mjviser's ``update_from_mjdata``
inside viser's ``atomic()``), and the real-time factor of whole grasp-then-place runs without a viewer and
with one that a headless Chromium (Debian's, through Playwright) is connected to, the run unpaced
(``Watch(speed=inf)``: about 32 frames per second of wall time, counted). Target: the viewer's own work (the
observer: scene updates and tree panel) costs under 20 % of the run's wall time. Reported beside it: the
whole slowdown, which on a 2-core machine includes the browser's software WebGL competing for the cores.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import time

import mujoco

from besman.sim.viewer import Viewer, headless_chromium
from besman.tasks.running import prepare
from besman.trees import grasp_then_place
from besman.trees.watching import Watch

# pick and place's 6 cm box at the task's default configuration (the seeds draw its mass and friction)
SETTINGS = {
    "object": (0.55, -0.08, 0.0),
    "place": (0.54, -0.41, 0.0),
    "shape": (0,),
    "size": (0.06, 0.06, 0.06),
}
TARGET_SHARE = 0.2


def timed(observe, seconds: list):
    """``observe`` that adds the wall time of each call to ``seconds``."""

    def call(runner, record):
        start = time.perf_counter()
        observe(runner, record)
        seconds.append(time.perf_counter() - start)

    return call


def counted(show, frames: list):
    """A viewer's ``show`` that adds the wall time of each frame it sent to ``frames``."""

    def call(data, *, force=False):
        sent = show(data, force=force)
        if sent:
            frames.append(time.perf_counter())
        return sent

    return call


def measure(runs: int) -> dict:
    from playwright.sync_api import sync_playwright

    runner = prepare("pick-place", grasp_then_place(), values=SETTINGS, seed=0).runner
    viewer = Viewer(runner.executor.world.model)
    plain, viewed, updates, shares, observing, rates, frames = [], [], [], [], [], [], []
    with sync_playwright() as playwright:
        browser = headless_chromium(playwright)
        page = browser.new_page(viewport={"width": 1280, "height": 800})
        page.goto(viewer.url)
        page.wait_for_function("document.body.innerText.includes('Behaviour tree')", timeout=60_000)
        data, arm = runner.executor.world.data, runner.executor.arm
        rest = data.qpos[arm.qpos_indices].copy()
        for k in range(200):  # a moving arm: every update sends new poses
            data.qpos[arm.qpos_indices] = rest + 0.01 * (k % 2)
            mujoco.mj_kinematics(runner.executor.world.model, data)
            start = time.perf_counter()
            viewer.show(data, force=True)
            updates.append(time.perf_counter() - start)
        viewer.show = counted(viewer.show, frames)
        for seed in range(runs):  # alternate, so that machine noise hits both alike
            for watched, factors in ((False, plain), (True, viewed)):
                runner = prepare("pick-place", grasp_then_place(), values=SETTINGS, seed=seed).runner
                if watched:
                    runner.observe = timed(Watch(viewer, speed=math.inf), observing)
                result = runner.run()
                factors.append(result.sim_time_s / result.wall_time_s)
                if watched:
                    shares.append(sum(observing) / result.wall_time_s)
                    rates.append((len(frames) - 1) / (frames[-1] - frames[0]))
                    observing.clear()
                    frames.clear()
        browser.close()
    viewer.close()
    without, with_viewer = statistics.median(plain), statistics.median(viewed)
    return {
        "runs": runs,
        "update_ms": 1e3 * statistics.median(updates),
        "real_time_factor_without_viewer": without,
        "real_time_factor_with_viewer": with_viewer,
        "viewer_share_of_wall_time": 1.0 - with_viewer / without,
        "server_side_share_of_wall_time": statistics.median(shares),
        "frames_per_second": statistics.median(rates),
        "target_share": TARGET_SHARE,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--runs", type=int, default=7)
    args = parser.parse_args()
    report = measure(args.runs)
    if args.json:
        print(json.dumps({"benchmark": "viewer", **report}, indent=2))
        return
    print(f"one scene update (AILA): {report['update_ms']:.2f} ms")
    print(
        f"grasp-then-place real-time factor: {report['real_time_factor_without_viewer']:.1f}x without a "
        f"viewer, {report['real_time_factor_with_viewer']:.1f}x with a connected one "
        f"({report['frames_per_second']:.0f} frames per second)"
    )
    own, whole, target = (
        report["server_side_share_of_wall_time"],
        report["viewer_share_of_wall_time"],
        100 * TARGET_SHARE,
    )
    print(
        f"the viewer's own work: {100 * own:.1f} % of the run's wall time (target < {target:.0f} %); "
        f"the whole slowdown with the browser connected: {100 * whole:.0f} %"
    )


if __name__ == "__main__":
    main()
