import os

# Offscreen rendering on machines without a screen; must precede the first `import mujoco`.
os.environ.setdefault("MUJOCO_GL", "egl")
