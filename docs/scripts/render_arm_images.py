"""Render a picture of each arm of rl_environments.robots that has no env ID yet (VX300S, UR5e, Ned2):
the arm on its table, holding its cube up after a top-down grasp, seen by its description's
``render_camera``.

Run from the repository root (headless machines need no display; EGL renders offscreen)::

    MUJOCO_GL=egl .venv/bin/python docs/scripts/render_arm_images.py

Writes ``docs/_static/arms/<arm>.png`` (640 x 480).
"""

from __future__ import annotations

import os
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402

from multiros.sim import launch  # noqa: E402
from rl_environments.arm_validation import ARMS, ArmScene  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


def render_arm(arm: str) -> np.ndarray:
    conn = launch.connect("composed", timestep=0.004)
    try:
        scene = ArmScene(arm, conn)
        pkg, s = scene.pkg, scene.scene
        xy = np.array([s["object_xy_max"][0] - 0.03, 0.6 * s["object_xy_min"][1]])
        scene.reset(xy, float(np.arctan2(xy[1], xy[0])))
        cube = scene.cube.copy()
        yaw = float(np.arctan2(cube[1], cube[0]) + np.pi / 2)
        for z, grip, steps in ((cube[2] + 0.06, pkg.GRIPPER_OPEN, 40), (cube[2] + scene.spec.grasp_depth,
                                                                         pkg.GRIPPER_OPEN, 40),
                               (None, pkg.GRIPPER_CLOSED, 15), (cube[2] + 0.12, pkg.GRIPPER_CLOSED, 40)):
            target = scene.ee_target if z is None else np.array([cube[0], cube[1], z])
            for _ in range(steps):
                scene.step(target, yaw, grip)
        return np.asarray(conn.read_camera(f"{scene.entity}/render_camera", width=640, height=480).rgb)
    finally:
        conn.close()


def main() -> None:
    out = ROOT / "docs" / "_static" / "arms"
    out.mkdir(parents=True, exist_ok=True)
    for arm in sorted(ARMS):
        Image.fromarray(render_arm(arm)).save(out / f"{arm}.png", optimize=True)
        print("wrote", out / f"{arm}.png")


if __name__ == "__main__":
    main()
