"""One HER agent from a simulated and a real (stand-in) RX200 at once: MultiTaskGoalEnv over
RX200ReacherGoalSim-v0 and RX200ReacherGoalReal-v0, the latter driving uniros-fake-robot in another
process over a private Zenoh router."""

from __future__ import annotations

import tempfile

import numpy as np
import pytest

from multiros.hardware.process import FakeRobotProcess
from multiros.sim.launch import private_context
from uniros.multitask import MultiTaskGoalEnv

pytestmark = [pytest.mark.multiprocess, pytest.mark.slow]


def test_one_her_agent_trains_on_sim_and_fake_real_robot():
    from stable_baselines3 import SAC, HerReplayBuffer

    ctx = private_context()
    try:
        with FakeRobotProcess("rx200", context=ctx, args=["--log-level", "WARNING"],
                              cwd=tempfile.gettempdir()):
            env = MultiTaskGoalEnv(
                ["RX200ReacherGoalSim-v0", "RX200ReacherGoalReal-v0"],
                [{"max_episode_steps": 20},
                 {"context": ctx, "max_episode_steps": 20, "environment_loop_rate": 20.0,
                  "reset_joint_speed": 4.0}],  # a first reset at the default 0.5 rad/s takes 6 s
                selection="round_robin")
            try:
                sim_space = env.envs[0].observation_space
                assert env.observation_space["observation"] == sim_space["observation"]  # same spaces: no padding
                model = SAC("MultiInputPolicy", env, replay_buffer_class=HerReplayBuffer,
                            replay_buffer_kwargs={"n_sampled_goal": 4, "goal_selection_strategy": "future"},
                            learning_starts=40, batch_size=64, seed=0, verbose=0, device="cpu")
                model.learn(total_timesteps=120)  # 6 episodes: 3 simulated, 3 on the fake robot
                buffer = model.replay_buffer
                ids = np.rint(buffer.observations["desired_goal"][: buffer.pos, 0, -1])
                # Round robin: episodes alternate sim (0), real (1), ... Each is at most 20 steps: one may end
                # sooner (a reached goal, or the real robot's timing), so runs, not counts, are checked.
                change = np.flatnonzero(np.diff(ids)) + 1
                runs = [(int(r[0]), len(r)) for r in np.split(ids, change)]
                assert [v for v, _ in runs] == [i % 2 for i in range(len(runs))], runs
                assert len(runs) >= 2 and all(n <= 20 for _, n in runs), runs
                assert sum(n for _, n in runs) == buffer.pos == 120
                samples = buffer.sample(128)
                rewards = samples.rewards.numpy().reshape(-1)
                expected = env.compute_reward(samples.next_observations["achieved_goal"].numpy(),
                                              samples.observations["desired_goal"].numpy(), [{}] * len(rewards))
                assert np.allclose(rewards, expected, atol=1e-5)
                obs, info = env.reset(options={"task_id": 1})
                obs, _, _, _, info = env.step(model.predict(obs, deterministic=True)[0])
                assert info["task_id"] == 1 and info["state_age_sec"] < 0.5  # a live robot state
            finally:
                env.close()
    finally:
        ctx.try_shutdown()
