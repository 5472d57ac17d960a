"""Render the pictures of the docs from the current code: one PNG per simulated env ID and one for the README.

Each image is the env's own ``render()`` (the robot's ``render_camera``; the Zed2 variants' Zed2)
right after ``reset``, for the first seed whose goal marker (and, for push and pick-and-place, the
cube) the robot does not hide from the camera; pick-and-place shows a goal in the air. The Real IDs
have no images of their own: they share the task and the robot with their Sim twin
(``rl_environments.SIM_TO_REAL``).

Run from the repository root (headless machines need no display; EGL renders offscreen)::

    MUJOCO_GL=egl .venv/bin/python docs/scripts/render_env_images.py

Writes ``docs/_static/envs/<ID>.png`` (640 x 480) and ``docs/_static/readme_robots.png`` (1200 x 300: the
RX200 reaching, the RX200 carrying the cube to a goal in the air, the IRB120 reaching). ``--ids`` renders
some IDs only.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402

import uniros  # noqa: E402
from multiros.sim.render import camera_pose, project_points  # noqa: E402
from rl_environments import ENV_IDS  # noqa: E402
from rl_environments.manipulation_scripted import scripted_policy  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SEEDS = range(40)


def _visible(env, point: np.ndarray, radius: float, body: str = "") -> bool:
    """No geom (but those of ``body``) between the env's render camera and a sphere at ``point``
    (rays to its centre and rim)."""
    world = env.sim_connection.sim_node.world  # the composed node's world (a docs tool may look inside)
    model, data = world.model, world.data
    exclude = mujoco.mj_name2id(model, int(mujoco.mjtObj.mjOBJ_BODY), body) if body else -1
    pos, axes, _ = camera_pose(model, data, env._render_options[0])
    groups = np.array([1, 1, 1, 0, 0, 0], dtype=np.uint8)
    geomid = np.zeros(1, dtype=np.int32)
    for offset in [np.zeros(3)] + [radius * s * axes[:, i] for i in (0, 1) for s in (-1.0, 1.0)]:
        vec = np.asarray(point, dtype=float) + offset - pos
        dist = float(np.linalg.norm(vec))
        hit = mujoco.mj_ray(model, data, pos, vec / dist, groups, 1, exclude, geomid)
        if 0 <= hit < dist - radius:
            return False
    return True


def _apart(env, a: np.ndarray, b: np.ndarray, pixels: float) -> bool:
    """``a`` and ``b`` at least ``pixels`` apart in the env's rendered image (the view says where each is)."""
    world = env.sim_connection.sim_node.world
    camera, width, height = env._render_options
    uv, _ = project_points(world.model, world.data, camera, [a, b], width=width, height=height)
    return bool(np.linalg.norm(uv[0] - uv[1]) >= pixels)


def _object(env) -> np.ndarray | None:
    return env.frame_position(env.task.object_frame) if hasattr(env.task, "object_frame") else None


def render_env(env_id: str, width: int, height: int) -> tuple[np.ndarray, int]:
    """The first frame after reset of the first seed showing the goal (and the object); returns it and the seed."""
    # A camera variant shows what its camera sees (the Zed2's left image), the others the robot's render camera.
    view = {"render_camera": "rx200/zed2_left"} if "Zed2" in env_id else {}
    env = uniros.make(env_id, render_mode="rgb_array", render_width=width, render_height=height, **view).unwrapped
    try:
        task = env.task
        radius = float(task.half) if hasattr(task, "half") else float(task.tolerance)
        for seed in SEEDS:
            env.reset(seed=seed)
            obj = _object(env)
            if task.NAME == "pnp" and task.goal[2] < task.table_top + 0.08:
                continue  # show what sets pick-and-place apart: a goal in the air
            if _visible(env, task.goal, radius) and (obj is None or _visible(env, obj, radius, task.object_frame)):
                return env.render(), seed
        raise RuntimeError(f"{env_id}: the robot hides the goal in every seed of {SEEDS}")
    finally:
        env.close()


def render_readme(width: int, height: int) -> np.ndarray:
    """Three panels side by side: the RX200 reaching, the RX200 carrying the cube (scripted
    pick-and-place) towards a goal in the air, the IRB120 reaching."""
    panel = width // 3
    env = uniros.make("RX200PnPGoalSim-v0", render_mode="rgb_array", render_width=panel, render_height=height)
    try:
        carry = None
        for seed in SEEDS:
            obs, _ = env.reset(seed=seed)
            task = env.unwrapped
            if task.goal[2] < task.table_top + 0.08:  # a goal well above the table
                continue
            policy = scripted_policy(task)
            for _ in range(50):
                obs, *_ = env.step(policy(obs))
                cube = _object(task)
                if cube[2] > task.table_top + 0.04 and _visible(task, cube, 0.6 * task.half, task.object_frame) \
                        and _visible(task, task.goal, task.half) and _apart(task, cube, task.goal, 0.15 * panel):
                    carry = env.render()
                    break
            if carry is not None:
                break
        else:
            raise RuntimeError(f"no seed of {SEEDS} shows the cube lifted, in view, towards a goal in the air")
    finally:
        env.close()
    rx200, _ = render_env("RX200ReacherGoalSim-v0", panel, height)
    irb120, _ = render_env("ABBIRB120ReacherGoalEnv-v0", panel, height)
    return np.hstack([rx200, carry, irb120])


def save(image: np.ndarray, path: Path) -> int:
    """Write a PNG, quantised to 256 colours (the renders' smooth shading keeps its look; files stay small)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(image).quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE) \
        .save(path, optimize=True)
    return path.stat().st_size


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "_static", help="the docs' _static folder")
    parser.add_argument("--ids", nargs="*", default=list(ENV_IDS), help="simulated env IDs (default: all)")
    parser.add_argument("--no-readme", action="store_true", help="skip the README picture")
    args = parser.parse_args(argv)
    unknown = sorted(set(args.ids) - set(ENV_IDS))
    if unknown:
        parser.error(f"not simulated env IDs: {unknown}; choose from {list(ENV_IDS)}")
    for env_id in args.ids:
        image, seed = render_env(env_id, 640, 480)
        size = save(image, args.out / "envs" / f"{env_id}.png")
        print(f"{env_id}: seed {seed}, {size // 1024} KB")
    if not args.no_readme:
        size = save(render_readme(1200, 300), args.out / "readme_robots.png")
        print(f"readme_robots.png: {size // 1024} KB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
