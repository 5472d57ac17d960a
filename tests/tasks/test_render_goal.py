"""Rendered images of the task envs: the goal marker in the first frame after every reset, on the
goal and nowhere else (composed and process mode), and each robot's camera framing the robot and
its whole goal region.

The goal's pixel comes from projecting it through the camera the env renders with
(:func:`multiros.sim.render.project_points` on the simulation node's world); a goal the robot
hides from the camera (a ray from the camera hits a geom first) is not expected to be seen.
"""

from __future__ import annotations

import itertools

import mujoco
import numpy as np
import pytest

import uniros
from multiros.sim.render import FreeCamera, camera_pose, project_points

SIM_IDS = [
    "RX200ReacherSim-v0", "RX200ReacherGoalSim-v0", "ABBIRB120ReacherEnv-v0", "ABBIRB120ReacherGoalEnv-v0",
    "RX200PushSim-v0", "RX200PushGoalSim-v0", "RX200PnPSim-v0", "RX200PnPGoalSim-v0",
]
WIDTH, HEIGHT = 320, 240
RESETS = 12

pytestmark = pytest.mark.slow  # each env renders (an EGL context, ~1 s) and resets a dozen times


def _world(env):
    return env.sim_connection.sim_node.world


def _camera(env):
    """The camera ``env.render()`` uses, as ``project_points`` takes it."""
    name = env._render_options[0]
    world = _world(env)
    return name if name else FreeCamera(*world.options.camera)


def _marker_radius(env) -> float:
    """Reach: a sphere of the goal tolerance; manipulation: of the object's size."""
    return float(env.task.half) if hasattr(env.task, "half") else float(env.task.tolerance)


def _green(patch: np.ndarray) -> np.ndarray:
    """Pixels of the goal marker's colour (rgba 0 1 0 0.8): nothing else in these scenes is green."""
    p = patch.astype(int)
    r, g, b = p[..., 0], p[..., 1], p[..., 2]
    return (g > 90) & (g > r + 50) & (g > b + 50)


class _View:
    """Pixel, apparent radius and visibility of world points in ``env``'s rendered images."""

    def __init__(self, env) -> None:
        self.world, self.camera = _world(env), _camera(env)

    def pixel(self, point: np.ndarray, radius: float) -> tuple[np.ndarray, float, float]:
        (uv,), (depth,) = project_points(self.world.model, self.world.data, self.camera, [point],
                                         width=WIDTH, height=HEIGHT)
        _, _, fovy = camera_pose(self.world.model, self.world.data, self.camera)
        focal = 0.5 * HEIGHT / np.tan(np.radians(fovy) / 2.0)
        return uv, focal * radius / depth, depth

    def visible(self, point: np.ndarray, radius: float) -> bool:
        """No geom between the camera and a sphere at ``point``: rays to its centre and to four
        points around it (the marker's whole face, as seen from the camera)."""
        model, data = self.world.model, self.world.data
        pos, axes, _ = camera_pose(model, data, self.camera)
        geomid = np.zeros(1, dtype=np.int32)
        groups = np.array([1, 1, 1, 0, 0, 0], dtype=np.uint8)  # the groups rendered images show
        offsets = [np.zeros(3)] + [radius * s * axes[:, i] for i in (0, 1) for s in (-1.0, 1.0)]
        for offset in offsets:
            vec = np.asarray(point, dtype=float) + offset - pos
            dist = float(np.linalg.norm(vec))
            hit = mujoco.mj_ray(model, data, pos, vec / dist, groups, 1, -1, geomid)
            if 0 <= hit < dist - radius:
                return False
        return True


def _inside(uv: np.ndarray, margin: float) -> bool:
    return bool(margin <= uv[0] <= WIDTH - margin and margin <= uv[1] <= HEIGHT - margin)


def _patch(image: np.ndarray, uv: np.ndarray, half: int) -> np.ndarray:
    c, r = int(uv[0]), int(uv[1])
    return image[max(r - half, 0):r + half + 1, max(c - half, 0):c + half + 1]


def _check_first_frames(env, view: _View, seeds, twin=None) -> int:
    """Reset, render at once and check the marker sits on the goal, not on the previous goal.
    ``twin``: a composed env of the same ID reset alongside (the view's world) when ``env`` runs
    its node elsewhere. Returns how many frames showed the goal (visible and inside the image)."""
    radius = _marker_radius(env)
    previous = None
    seen = 0
    for seed in seeds:
        env.reset(seed=seed)
        image = env.render()
        if twin is not None:
            twin.reset(seed=seed)
            assert np.allclose(twin.task.goal, env.task.goal), "the composed twin has another goal"
        goal = np.asarray(env.task.goal, dtype=float)
        uv, r_px, depth = view.pixel(goal, radius)
        if depth > 0 and _inside(uv, r_px + 2) and view.visible(goal, radius):
            half = max(int(r_px * 0.4), 1)
            share = _green(_patch(image, uv, half)).mean()
            assert share > 0.6, (
                f"seed {seed}: the first frame after reset does not show the goal marker at the goal "
                f"{goal.round(3).tolist()} (pixel {uv.round(1).tolist()}, {share:.0%} marker colour)")
            seen += 1
        if previous is not None:
            p_uv, p_r, p_depth = view.pixel(previous, radius)
            apart = np.linalg.norm(p_uv - uv) > r_px + p_r + 3
            if apart and p_depth > 0 and _inside(p_uv, p_r + 2) and view.visible(previous, radius):
                half = max(int(p_r * 0.4), 1)
                assert _green(_patch(image, p_uv, half)).mean() < 0.2, (
                    f"seed {seed}: the first frame after reset still shows the previous episode's goal "
                    f"marker at {previous.round(3).tolist()}")
        previous = goal
    return seen


@pytest.mark.parametrize("env_id", SIM_IDS)
def test_first_frame_after_reset_shows_the_goal_marker(env_id):
    env = uniros.make(env_id, render_mode="rgb_array", render_width=WIDTH, render_height=HEIGHT).unwrapped
    try:
        seen = _check_first_frames(env, _View(env), range(RESETS))
    finally:
        env.close()
    assert seen >= RESETS // 2, f"only {seen} of {RESETS} goals were in view and unhidden"


@pytest.mark.multiprocess
@pytest.mark.parametrize("env_id", ["ABBIRB120ReacherGoalEnv-v0", "RX200PushGoalSim-v0"])
def test_first_frame_after_reset_shows_the_goal_marker_in_process_mode(env_id):
    env = uniros.make(env_id, sim_mode="process", render_mode="rgb_array", render_width=WIDTH,
                      render_height=HEIGHT).unwrapped
    twin = uniros.make(env_id, render_mode="rgb_array", render_width=WIDTH, render_height=HEIGHT).unwrapped
    try:
        seen = _check_first_frames(env, _View(twin), range(RESETS), twin=twin)
    finally:
        env.close()
        twin.close()
    assert seen >= RESETS // 2, f"only {seen} of {RESETS} goals were in view and unhidden"


def _corners(low, high) -> np.ndarray:
    return np.array(list(itertools.product(*zip(low, high))), dtype=float)


def _goal_region(env, samples: int = 1500) -> np.ndarray:
    """World points the default image must show, each grown by the marker's radius: many sampled
    goals; manipulation: object starts too, and the corners of the box they span; a reach goal box
    the arm reaches everywhere (the RX200's): its corners. The IRB120's goal box (1 m, centred on
    the base) reaches beyond the arm, and the sampler draws from its reachable part only."""
    rng = np.random.default_rng(0)
    if hasattr(env.task, "sampler"):  # manipulation: (object position, yaw, goal) relative to the base
        draws = [env.task.sampler.sample(rng) for _ in range(samples)]
        points = np.array([p for obj, _, goal in draws for p in (obj, goal)]) + env.task.base_position
        points = np.vstack([points, _corners(points.min(0), points.max(0))])
    else:
        points = np.array([env.task.goal_sampler.sample(rng) for _ in range(samples)])
        if env.robot_name == "rx200":
            points = np.vstack([points, _corners(env.task.goal_min, env.task.goal_max)])
    grow = np.vstack([np.eye(3), -np.eye(3)]) * _marker_radius(env)
    return (points[:, None, :] + grow[None]).reshape(-1, 3)


@pytest.mark.parametrize("env_id", SIM_IDS)
def test_default_camera_frames_the_robot_and_every_goal(env_id):
    env = uniros.make(env_id).unwrapped
    try:
        env.reset(seed=0)
        camera = env._render_options[0]
        assert camera == f"{env.robot_name}/render_camera"
        world = _world(env)
        region = _goal_region(env)
        robot = _corners(*world.bounds(env.robot_name))
        for width, height in ((480, 480), (640, 480)):  # the envs' default size, the docs' images
            margin = 0.03 * height
            uv, depth = project_points(world.model, world.data, camera, region, width=width, height=height)
            assert np.all(depth > 0)
            outside = ~((uv[:, 0] >= margin) & (uv[:, 0] <= width - margin)
                        & (uv[:, 1] >= margin) & (uv[:, 1] <= height - margin))
            assert not outside.any(), (
                f"{width}x{height}: goal region points at the image edge or outside: {region[outside][:3].round(3)}")
            uv, depth = project_points(world.model, world.data, camera, robot, width=width, height=height)
            lo, hi = np.clip(uv.min(0), 0, (width, height)), np.clip(uv.max(0), 0, (width, height))
            assert np.all(depth > 0)
            # The robot (its bounding box at the start pose) spans a good part of the image.
            assert hi[1] - lo[1] > 0.4 * height and (hi - lo).prod() > 0.15 * width * height, (
                f"{width}x{height}: the robot spans only {(hi - lo).round().tolist()} pixels")
    finally:
        env.close()


def test_default_camera_can_be_replaced():
    env = uniros.make("RX200ReacherGoalSim-v0", render_mode="rgb_array", render_camera="", render_width=64,
                      render_height=48).unwrapped
    try:
        env.reset(seed=0)
        assert env._render_options[0] == "" and env.render().shape == (48, 64, 3)  # the node's default view
    finally:
        env.close()
