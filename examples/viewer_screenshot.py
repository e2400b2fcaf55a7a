"""A screenshot of the browser viewer during grasp-then-place, taken the way the tests see it.

    python examples/viewer_screenshot.py [--out docs/viewer.png]

Runs the demo's tree at real time with a viewer, opens it in Debian's headless Chromium (Playwright), and
saves the page once the robot carries the box.
"""

from __future__ import annotations

import argparse
import threading

from playwright.sync_api import sync_playwright

from besman.sim.viewer import Viewer, headless_chromium
from besman.skills.storage import check_output, write_atomically
from besman.trees import grasp_then_place
from besman.trees.tabletop import tabletop_run
from besman.trees.watching import Watch


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/viewer.png")
    out = check_output(parser.parse_args().out, option="--out", suffixes=(".png",))
    runner, _ = tabletop_run(grasp_then_place(), {"object": (0.55, -0.08), "place": (0.54, -0.41)}, seed=0)
    viewer = Viewer(runner.executor.world.model)
    runner.observe = Watch(viewer, speed=1.0)
    run = threading.Thread(target=runner.run)
    with sync_playwright() as playwright:
        browser = headless_chromium(playwright)
        page = browser.new_page(viewport={"width": 1280, "height": 800})
        page.goto(viewer.url)
        page.wait_for_function("document.body.innerText.includes('Behaviour tree')", timeout=60_000)
        run.start()
        page.wait_for_function("document.body.innerText.includes('transport RUNNING')", timeout=60_000)
        write_atomically(out, page.screenshot())
        browser.close()
    run.join()
    viewer.close()
    print(out)


if __name__ == "__main__":
    main()
