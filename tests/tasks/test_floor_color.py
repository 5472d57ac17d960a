"""``floor_color``: the floor of rendered images, an option of a node an env starts (composed, a vector env's
workers, process mode, ``uniros-sim --floor-color``); refused for a node someone else started or a name
nobody knows. Camera observations see it; physics does not (the same trajectory either way)."""

from __future__ import annotations

import numpy as np
import pytest

import uniros
from multiros.sim.program import _parser
from multiros.sim.world import World, WorldOptions

ENV = "IRB120ReacherGoalSim-v0"
CAMERA = {"ee_action_type": True, "rgb_obs_only": True, "image_width": 32, "image_height": 32,
          "camera_position": [0.938, -0.368, 0.675], "camera_lookat": [0.3, 0.0, 0.25]}


def _floor_rows(image: np.ndarray) -> float:
    """The mean level of the bottom quarter of a camera image: floor only in this view."""
    return float(image[-image.shape[0] // 4:].mean())


def test_a_dark_floor_darkens_camera_images_and_leaves_the_physics_alone() -> None:
    seen, joints = {}, {}
    for color in ("light", "dark"):
        env = uniros.make(ENV, floor_color=color, **CAMERA)
        try:
            obs, _ = env.reset(seed=3)
            seen[color] = _floor_rows(obs["observation"])
            for _ in range(3):
                obs, *_ = env.step(np.full(env.action_space.shape, 0.5, np.float32))
            joints[color] = np.asarray(obs["achieved_goal"]).copy()
        finally:
            env.close()
    assert seen["light"] > 150 and seen["dark"] < 80, seen
    np.testing.assert_array_equal(joints["light"], joints["dark"])


@pytest.mark.parametrize("how", [pytest.param({}, id="vector-workers"),
                                 pytest.param({"sim_mode": "process"}, id="process-mode")])
def test_the_nodes_a_vector_env_or_process_mode_starts_take_the_floor(how: dict) -> None:
    """make_vec's nodes (in its workers, or process mode's children, started with --floor-color)."""
    vec = uniros.make_vec(ENV, 2, floor_color="dark", **CAMERA, **how)
    try:
        obs, _ = vec.reset(seed=0)
        assert max(_floor_rows(image) for image in obs["observation"]) < 80
    finally:
        vec.close()


def test_a_floor_nobody_knows_or_of_a_node_someone_else_started_is_refused() -> None:
    with pytest.raises(ValueError, match=r"floor_color must be one of \['dark', 'light'\], got 'pink'"):
        uniros.make(ENV, floor_color="pink")
    with pytest.raises(ValueError, match="the existing node keeps its own"):
        uniros.make(ENV, floor_color="dark", sim_mode="existing", sim_node_name="nobody_runs_this_node")
    with pytest.raises(ValueError, match="floor_color must be one of"):
        World(WorldOptions(floor_color="Dark"))
    assert _parser().parse_args(["--floor-color", "dark"]).floor_color == "dark"
    with pytest.raises(SystemExit):
        _parser().parse_args(["--floor-color", "pink"])
