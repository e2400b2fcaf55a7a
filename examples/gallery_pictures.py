"""The demo gallery's pictures (docs/gallery): each task's demo with a fixed seed, drawn where it shows most.

    python examples/gallery_pictures.py [--out docs/gallery]

Each picture is MuJoCo's offscreen rendering of the task's world at one tick of its demo (its default tree;
sort: the last box being set down beside the others; handover: both hands on the bar; throwing: the ball in
flight; pick-place: the box carried to the shelf), from a camera aimed at what the demo is about. The files
keep the demos' earlier names (grasp-then-place.png, throw.png), which the documentation links.
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported

from pathlib import Path

import mujoco

from besman.robots.render import save_png
from besman.tasks.running import prepare

# task -> (picture's file name, seed, fraction of the run's ticks at which to draw, camera: look-at, distance,
# azimuth, elevation)
SHOTS = {
    "pick-place": ("grasp-then-place", 0, 0.55, (0.55, -0.25, 0.9), 1.5, 200.0, -25.0),
    "sort": ("sort", 0, 0.93, (0.55, -0.25, 0.9), 1.6, 205.0, -30.0),
    "handover": ("handover", 0, 0.42, (0.45, 0.0, 0.95), 1.3, 180.0, -25.0),
    "throwing": ("throw", 3, 0.5, (-2.5, -1.5, 0.8), 7.0, 135.0, -15.0),
}


def picture(name: str, out: Path) -> Path:
    file, seed, fraction, lookat, distance, azimuth, elevation = SHOTS[name]
    prepared = prepare(name, seed=seed, demo=name)
    world = prepared.runner.executor.world
    frames = []

    def snapshot(runner, record):
        frames.append(world.data.qpos.copy())

    previous = prepared.runner.observe
    prepared.runner.observe = lambda runner, record: (
        previous and previous(runner, record),
        snapshot(runner, record),
    )
    prepared.runner.run()
    data = mujoco.MjData(world.model)
    data.qpos[:] = frames[int(fraction * (len(frames) - 1))]
    mujoco.mj_forward(world.model, data)
    camera = mujoco.MjvCamera()
    camera.lookat[:], camera.distance, camera.azimuth, camera.elevation = lookat, distance, azimuth, elevation
    with mujoco.Renderer(world.model, 480, 640) as renderer:
        renderer.update_scene(data, camera)
        image = renderer.render()
    return save_png(image, out / f"{file}.png")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/gallery", help="folder of the PNGs")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name in SHOTS:
        print(picture(name, out))


if __name__ == "__main__":
    main()
