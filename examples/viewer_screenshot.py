"""A screenshot of the browser viewer during grasp-then-place, taken the way the tests see it.

    python examples/viewer_screenshot.py [--out docs/viewer.png]

Serves the demo's tree in a browser session (what ``besman demo --view`` serves), opens it in Debian's
headless Chromium (Playwright), clicks Run, and saves the page once the robot carries the box: the scene with
the planned (blue) and executed (orange) hand paths, the target frame and the place ring, and the tree panel.
"""

from __future__ import annotations

import argparse

from playwright.sync_api import sync_playwright

from besman.core.storage import check_output, write_atomically
from besman.sim.viewer import headless_chromium
from besman.tasks import task
from besman.tasks.session import Session


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/viewer.png")
    out = check_output(parser.parse_args().out, option="--out", suffixes=(".png",))
    pick_place = task("pick-place")
    session = Session(pick_place.tree_path, task=pick_place.name, demo=pick_place.name)  # its default values
    with sync_playwright() as playwright:
        browser = headless_chromium(playwright)
        page = browser.new_page(viewport={"width": 1280, "height": 800})
        page.goto(session.url)
        page.wait_for_function("document.body.innerText.includes('Behaviour tree')", timeout=60_000)
        page.wait_for_timeout(3000)  # software WebGL: the scene fades in
        # Headless Chromium renders WebGL in software and the page says so: not what a reader's browser shows.
        page.add_style_tag(content=".mantine-Notifications-root { display: none !important; }")
        page.get_by_role("button", name="Run", exact=True).click()
        page.wait_for_function("document.body.innerText.includes('carry RUNNING')", timeout=60_000)
        page.wait_for_timeout(700)
        write_atomically(out, page.screenshot())
        browser.close()
    session.close()
    print(out)


if __name__ == "__main__":
    main()
