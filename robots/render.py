"""Offscreen pictures of a robot's scene with MuJoCo's renderer.

Rendering needs an OpenGL context without a screen: set ``MUJOCO_GL=egl`` (or ``osmesa``) before ``mujoco``
is first imported. The ``besman`` command line does that for you.
"""

from __future__ import annotations

import io
import os
from pathlib import Path

import mujoco
import numpy as np

from besman.core.errors import InputError
from besman.core.storage import check_output, write_atomically
from besman.robots.robot import Robot


def render(
    robot: Robot,
    *,
    width: int = 960,
    height: int = 720,
    keyframe: str | None = None,
    azimuth: float | None = None,
    elevation: float | None = None,
    distance: float | None = None,
) -> np.ndarray:
    """An RGB image (height, width, 3) of the robot's scene in ``keyframe`` (default: its home keyframe).

    The camera is a free camera aimed at the model's ``statistic`` centre; ``azimuth``/``elevation`` (deg) and
    ``distance`` (m) override the scene's defaults.
    """
    model = robot.model
    if width > model.vis.global_.offwidth or height > model.vis.global_.offheight:
        raise InputError(
            f"image {width}x{height} exceeds the scene's offscreen buffer "
            f"{model.vis.global_.offwidth}x{model.vis.global_.offheight}"
        )
    data = robot.make_data(keyframe)
    camera = mujoco.MjvCamera()
    mujoco.mjv_defaultFreeCamera(model, camera)
    if azimuth is not None:
        camera.azimuth = azimuth
    if elevation is not None:
        camera.elevation = elevation
    if distance is not None:
        camera.distance = distance
    try:
        renderer = mujoco.Renderer(model, height, width)
    except Exception as error:  # MuJoCo raises bare Exceptions when no GL context can be made
        raise RuntimeError(
            f"offscreen rendering is not available ({error}); set MUJOCO_GL=egl (or osmesa) before importing "
            f"mujoco (currently MUJOCO_GL={os.environ.get('MUJOCO_GL')!r})"
        ) from None
    with renderer:
        renderer.update_scene(data, camera)
        return renderer.render().copy()


def png_path(path: str | Path) -> Path:
    """``path`` as a Path, if it names a PNG file that can be written; a ValueError otherwise."""
    return check_output(path, option="--out", suffixes=(".png",))


def save_png(image: np.ndarray, path: str | Path) -> Path:
    """Writes an RGB image as PNG atomically (temporary file, then rename)."""
    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(image).save(buffer, format="PNG")
    return write_atomically(png_path(path), buffer.getvalue())
