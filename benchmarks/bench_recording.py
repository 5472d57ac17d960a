"""What recording a LeRobot dataset costs against the env's own step rate (issue 53's goal: <= 10 % slower).

Plays the same scripted episodes (seeds 0..N-1) of an env twice, alternately, ``--rounds`` times: once
only stepping it, once through :func:`uniros.recording.record` (frames buffered, one parquet row group
an episode, the metadata at the end), without images, and prints the step rates and the slowdown of the
best round of each::

    .venv/bin/python benchmarks/bench_recording.py [--env RX200PushGoalSim-v0] [--episodes 20] [--rounds 3]
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

from uniros.recording import record
from uniros.run_envs import make_env


def _plain(env: object, policy: object, episodes: int) -> tuple[int, float]:
    steps, start = 0, time.perf_counter()
    for k in range(episodes):
        obs, _ = env.reset(seed=k)  # type: ignore[attr-defined]
        policy.reset()  # type: ignore[attr-defined]
        done = False
        while not done:
            obs, _, terminated, truncated, _ = env.step(policy(obs))  # type: ignore[attr-defined, operator]
            steps += 1
            done = terminated or truncated
    return steps, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--env", default="RX200PushGoalSim-v0")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    env = make_env(args.env)
    policy = env.unwrapped.task.scripted_policy()
    tmp = Path(tempfile.mkdtemp(prefix="bench_recording_"))
    plain, recorded = [], []
    try:
        _plain(env, policy, 2)  # warm up: the env, and the writer's imports (pyarrow: once a process)
        record(env, policy, 1, tmp / "warm", env_id=args.env, progress=False, reset=policy.reset)
        for r in range(args.rounds):
            steps, seconds = _plain(env, policy, args.episodes)
            plain.append(steps / seconds)
            start = time.perf_counter()
            result = record(env, policy, args.episodes, tmp / f"ds{r}", env_id=args.env, progress=False,
                            reset=policy.reset)
            recorded.append(result["frames"] / (time.perf_counter() - start))
    finally:
        env.close()
        shutil.rmtree(tmp, ignore_errors=True)
    best_plain, best_rec = max(plain), max(recorded)
    print(f"{args.env}, {args.episodes} scripted episodes x {args.rounds} rounds, no images")
    print(f"  env alone      {best_plain:8.1f} steps/s  (rounds: {', '.join(f'{x:.0f}' for x in plain)})")
    print(f"  recording      {best_rec:8.1f} steps/s  (rounds: {', '.join(f'{x:.0f}' for x in recorded)})")
    print(f"  slowdown       {100 * (1 - best_rec / best_plain):8.1f} %  (goal: <= 10 %)")


if __name__ == "__main__":
    main()
