"""Concurrent sim + real training (UniROS' MultiTaskGoalEnv) against the fake robot stand-in.

One HER+SAC agent learns from RX200ReacherGoalSim-v0 and RX200ReacherGoalReal-v0 at once (one
episode of either at a time, round robin); the Real env drives ``uniros-fake-robot`` in another
process over a private Zenoh router, in real time. Then the same model is evaluated on each env and
the figures printed side by side: env steps and wall-clock seconds spent per side, success rates.

    .venv/bin/python benchmarks/bench_sim_real_multitask.py --steps 3000 --episodes 10
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from multiros.hardware.process import FakeRobotProcess
from multiros.sim.launch import private_context
from uniros.multitask import MultiTaskGoalEnv

SIM, REAL = "RX200ReacherGoalSim-v0", "RX200ReacherGoalReal-v0"


class _Timed:
    """Counts steps and wall time per task while SB3 trains."""

    def __init__(self, env: MultiTaskGoalEnv) -> None:
        self.steps = np.zeros(env.num_tasks, dtype=int)
        self.seconds = np.zeros(env.num_tasks)
        inner = env.step

        def step(action):
            task, start = env.task_id, time.perf_counter()
            out = inner(action)
            self.steps[task] += 1
            self.seconds[task] += time.perf_counter() - start
            return out

        env.step = step  # type: ignore[method-assign]


def _success(model, env: MultiTaskGoalEnv, task: int, episodes: int, seed: int) -> float:
    wins = 0
    for ep in range(episodes):
        obs, info = env.reset(seed=seed + ep, options={"task_id": task})
        done = False
        while not done:
            obs, _, terminated, truncated, info = env.step(model.predict(obs, deterministic=True)[0])
            done = terminated or truncated
        wins += bool(info.get("is_success", False))
    return wins / episodes


def main() -> None:
    from stable_baselines3 import SAC, HerReplayBuffer

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=3000, help="training steps over both envs")
    parser.add_argument("--episodes", type=int, default=10, help="evaluation episodes per env")
    parser.add_argument("--episode-steps", type=int, default=50, help="max steps of an episode")
    parser.add_argument("--loop-rate", type=float, default=10.0, help="Real env environment_loop_rate (Hz)")
    args = parser.parse_args()

    ctx = private_context()
    try:
        with FakeRobotProcess("rx200", context=ctx, args=["--log-level", "WARNING"]):
            env = MultiTaskGoalEnv(
                [SIM, REAL],
                [{"max_episode_steps": args.episode_steps},
                 {"context": ctx, "max_episode_steps": args.episode_steps, "environment_loop_rate": args.loop_rate}],
                selection="round_robin")
            try:
                timed = _Timed(env)
                model = SAC("MultiInputPolicy", env, replay_buffer_class=HerReplayBuffer,
                            replay_buffer_kwargs={"n_sampled_goal": 4, "goal_selection_strategy": "future"},
                            learning_starts=min(1000, args.steps // 2), batch_size=256, gamma=0.95, seed=0,
                            device="cpu", verbose=0)
                start = time.perf_counter()
                model.learn(total_timesteps=args.steps)
                train_s = time.perf_counter() - start
                steps, seconds = timed.steps.copy(), timed.seconds.copy()  # training only
                rates = [_success(model, env, task, args.episodes, seed=1000) for task in (0, 1)]
            finally:
                env.close()
    finally:
        ctx.try_shutdown()
    print(f"trained {args.steps} steps in {train_s:.1f} s (one SAC+HER agent, one replay buffer)")
    print(f"{'env':<38}{'steps':>8}{'env s':>9}{'steps/s':>10}{'success':>10}")
    for task, name in enumerate((SIM, REAL + " (fake robot)")):
        rate = steps[task] / max(seconds[task], 1e-9)
        print(f"{name:<38}{steps[task]:>8}{seconds[task]:>9.1f}{rate:>10.1f}{rates[task]:>10.2f}")


if __name__ == "__main__":
    main()
