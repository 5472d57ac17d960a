"""The goal reach tasks' batched step hooks (rl_environments.reach_batch): a batched vector env with
them gives bit for bit what its envs' own hooks give, and steps env by env wherever they do not apply."""

from __future__ import annotations

import numpy as np
import pytest

import uniros
from rl_environments.abb_irb120.sim.task_envs.reacher.irb120_reacher_goal import ABBIRB120ReacherGoalEnv
from rl_environments.reach_batch import GoalReachBatchHooks
from rl_environments.rx200.sim.task_envs.reach.rx200_reach_goal_sim import RX200ReacherGoalEnv


def _pair(env_id: str, n: int, **kwargs):
    """Two identical batched vector envs, the second without batched hooks (its envs' own hooks)."""
    fast = uniros.make_vec(env_id, n, vectorization_mode="batched", max_episode_steps=8, **kwargs)
    slow = uniros.make_vec(env_id, n, vectorization_mode="batched", max_episode_steps=8, **kwargs)
    assert isinstance(fast.batch.hooks, GoalReachBatchHooks)
    slow.batch.hooks = None
    return fast, slow


@pytest.mark.parametrize(("env_id", "kwargs"), [
    ("RX200ReacherGoalSim-v0", {}),
    ("RX200ReacherGoalSim-v0", {"reward_type": "dense"}),
    ("RX200ReacherGoalSim-v0", {"delta_action": False}),
    ("RX200ReacherGoalSim-v0", {"ee_action_type": True}),  # IK actions: env by env, results batched
    ("RX200ReacherGoalSim-v0", {"vector_kwargs": {"num_nodes": 2}}),
    ("ABBIRB120ReacherGoalEnv-v0", {}),
])
def test_batched_hooks_equal_the_envs_own_hooks(env_id: str, kwargs: dict) -> None:
    """Observations, rewards, terminations, truncations, infos and the envs' task state are equal
    bit for bit, with actions beyond the bounds (clipped) and across autoresets."""
    n = 3
    fast, slow = _pair(env_id, n, **kwargs)
    try:
        for vec in (fast, slow):
            vec.reset(seed=3)
        rng = np.random.default_rng(1)
        low, high = fast.single_action_space.low, fast.single_action_space.high
        for _ in range(20):
            actions = rng.uniform(low - 0.5 * (high - low), high + 0.5 * (high - low), (n, *low.shape))
            actions = actions.astype(np.float32)
            out_fast, out_slow = fast.step(actions), slow.step(actions)
            for key in out_fast[0]:
                np.testing.assert_array_equal(out_fast[0][key], out_slow[0][key], err_msg=key)
            for a, b in zip(out_fast[1:4], out_slow[1:4]):
                np.testing.assert_array_equal(a, b)
            assert out_fast[4].keys() == out_slow[4].keys()
            for key in out_fast[4]:
                np.testing.assert_array_equal(out_fast[4][key], out_slow[4][key], err_msg=key)
            for ef, es in zip(fast.envs, slow.envs):
                np.testing.assert_array_equal(ef.prev_action, es.prev_action)
                np.testing.assert_array_equal(ef.joint_targets, es.joint_targets)
                np.testing.assert_array_equal(ef.goal, es.goal)
    finally:
        fast.close()
        slow.close()


def test_a_replaced_hook_turns_the_batched_hooks_off() -> None:
    class OwnObservation(RX200ReacherGoalEnv):
        def _get_obs(self):
            return super()._get_obs()

    class MultiRosAction(RX200ReacherGoalEnv):
        def _send_action(self, action):  # the MultiROS name of _set_action wins when defined lower
            self._set_action(action)

    class OwnReward(ABBIRB120ReacherGoalEnv):
        def compute_reward(self, achieved_goal, desired_goal, info):
            return super().compute_reward(achieved_goal, desired_goal, info)

    assert isinstance(RX200ReacherGoalEnv.batch_step_hooks(), GoalReachBatchHooks)
    assert isinstance(ABBIRB120ReacherGoalEnv.batch_step_hooks(), GoalReachBatchHooks)
    for cls in (OwnObservation, MultiRosAction, OwnReward):
        assert cls.batch_step_hooks() is None, cls.__name__


def test_batched_hooks_step_env_by_env_where_they_do_not_apply() -> None:
    """A bad action gets the env's own error; an env with its own command hook, end-effector
    actions or another reward type is served by its own hooks, and the results stay equal."""
    fast, slow = _pair("RX200ReacherGoalSim-v0", 2)
    try:
        for vec in (fast, slow):
            vec.reset(seed=5)
        bad = np.zeros((2, 5), np.float32)
        bad[1, 2] = np.nan
        with pytest.raises(ValueError, match="NaN or infinite"):
            fast.step(bad)
        with pytest.raises(ValueError, match="NaN or infinite"):
            slow.step(bad)
        hooks = fast.batch.hooks
        assert not hooks.act(fast.envs, bad)  # declined, nothing changed
        sent = []
        for vec in (fast, slow):  # an instance's own send_command is used, not bypassed
            env = vec.envs[0]
            env.send_command = lambda controller, values, env=env: (
                sent.append(controller), env._pending_commands.__setitem__(controller, np.asarray(values)))
        fast.set_attr("reward_type", ["dense", "sparse"])
        slow.set_attr("reward_type", ["dense", "sparse"])
        assert hooks.results(fast.envs) is None
        rng = np.random.default_rng(2)
        for _ in range(4):
            actions = rng.uniform(-1, 1, (2, 5)).astype(np.float32)
            (of, rf, *_), (os_, rs, *_) = fast.step(actions), slow.step(actions)
            np.testing.assert_array_equal(of["observation"], os_["observation"])
            np.testing.assert_array_equal(rf, rs)
        assert len(sent) == 8
        assert rf[0] < 0 and rf[0] not in (0.0, -1.0)  # env 0 is dense now
    finally:
        fast.close()
        slow.close()


def test_envs_reading_their_state_their_own_way_are_served_their_own_parts() -> None:
    """The joint and frame parts are sliced from the node's stacked states only for envs that read
    their state the stock way: an env instance (or a class) with its own ``ee_position`` gets the
    parts its own ``_obs_part`` gives, and the results stay bit for bit equal."""
    class OwnVelocities(RX200ReacherGoalEnv):
        def arm_velocities(self):
            return 0.5 * super().arm_velocities()

    assert RX200ReacherGoalEnv.batch_step_hooks().reads_stacked
    assert not OwnVelocities.batch_step_hooks().reads_stacked
    fast, slow = _pair("RX200ReacherGoalSim-v0", 3)
    try:
        for vec in (fast, slow):
            vec.reset(seed=9)
            env = vec.envs[1]
            env.ee_position = lambda env=env: env.frame_position(env.EE_LINK) + 0.01
        rng = np.random.default_rng(4)
        for _ in range(5):
            actions = rng.uniform(-1, 1, (3, 5)).astype(np.float32)
            (of, rf, *_), (os_, rs, *_) = fast.step(actions), slow.step(actions)
            for key in of:
                np.testing.assert_array_equal(of[key], os_[key], err_msg=key)
            np.testing.assert_array_equal(rf, rs)
        env = fast.envs[1]
        np.testing.assert_allclose(of["achieved_goal"][1], np.clip(
            env.frame_position(env.EE_LINK) + 0.01, env.observation_space["achieved_goal"].low,
            env.observation_space["achieved_goal"].high).astype(np.float32))
    finally:
        fast.close()
        slow.close()
