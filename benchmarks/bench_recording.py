"""What recording a LeRobot dataset costs against the env's own step rate (issue 53's goal: <= 10 % slower).

Plays the same scripted episodes (seeds 0..N-1) of an env twice, alternately, ``--rounds`` times: once
only stepping it, once through :func:`uniros.recording.record` (frames buffered, one parquet row group
an episode, the metadata at the end), and prints the step rates and the slowdown of the best round of each.

``--images`` makes the env with a camera (``rgb_plus_normal_obs``, ``--image-size``, 84x84 by default) in
both cases, so that the slowdown is what writing the frames as video costs (rendering is the env's own
cost), and prints the video's size::

    .venv/bin/python benchmarks/bench_recording.py [--env RX200PushGoalSim-v0] [--episodes 20] [--rounds 3]
    .venv/bin/python benchmarks/bench_recording.py --images [--image-size 84x84] [--video-codec h264]
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

from uniros.lerobot_dataset import DatasetWriter
from uniros.lerobot_video import VideoSettings
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


class _WriterClock:
    """Times the writer's own calls (add_frame, save_episode, finalize) inside the recording rounds: what
    recording adds to a step, measured in the same run as the steps, so a busy machine skews it less."""

    def __init__(self) -> None:
        self.seconds = 0.0
        for name in ("add_frame", "save_episode", "finalize"):
            setattr(DatasetWriter, name, self._timed(getattr(DatasetWriter, name)))

    def _timed(self, method: Any) -> Any:
        def timed(*args: Any, **kwargs: Any) -> Any:
            start = time.perf_counter()
            try:
                return method(*args, **kwargs)
            finally:
                self.seconds += time.perf_counter() - start
        return timed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--env", default="RX200PushGoalSim-v0")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--images", action="store_true", help="a camera, its frames recorded as video")
    parser.add_argument("--image-size", default="84x84", metavar="WxH")
    parser.add_argument("--video-codec", default="h264")
    parser.add_argument("--crf", type=int, default=23)
    args = parser.parse_args()
    width, height = (int(n) for n in args.image_size.split("x"))
    kwargs = {"rgb_plus_normal_obs": True, "image_width": width, "image_height": height} if args.images else {}
    video = VideoSettings(codec=args.video_codec, crf=args.crf)
    env = make_env(args.env, **kwargs)
    policy = env.unwrapped.task.scripted_policy()
    tmp = Path(tempfile.mkdtemp(prefix="bench_recording_"))
    plain, recorded, writing = [], [], []
    video_bytes = 0
    clock = _WriterClock()
    try:
        _plain(env, policy, 2)  # warm up: the env, and the writer's imports (pyarrow: once a process)
        record(env, policy, 1, tmp / "warm", env_id=args.env, progress=False, reset=policy.reset,
               images=args.images, video=video)
        for r in range(args.rounds):
            steps, seconds = _plain(env, policy, args.episodes)
            plain.append(steps / seconds)
            start, clock.seconds = time.perf_counter(), 0.0
            result = record(env, policy, args.episodes, tmp / f"ds{r}", env_id=args.env, progress=False,
                            reset=policy.reset, images=args.images, video=video)
            recorded.append(result["frames"] / (time.perf_counter() - start))
            writing.append(clock.seconds / result["frames"])
            video_bytes = sum(f.stat().st_size for f in (tmp / f"ds{r}").glob("videos/**/*.mp4"))
            frames = result["frames"]
    finally:
        env.close()
        shutil.rmtree(tmp, ignore_errors=True)
    best_plain, best_rec = max(plain), max(recorded)
    what = (f"images {width}x{height} as {args.video_codec} video (crf {args.crf}) in both" if args.images
            else "no images")
    print(f"{args.env}, {args.episodes} scripted episodes x {args.rounds} rounds, {what}")
    print(f"  env alone      {best_plain:8.1f} steps/s  (rounds: {', '.join(f'{x:.0f}' for x in plain)})")
    print(f"  recording      {best_rec:8.1f} steps/s  (rounds: {', '.join(f'{x:.0f}' for x in recorded)})")
    print(f"  slowdown       {100 * (1 - best_rec / best_plain):8.1f} %  (goal: <= 10 %)")
    write = min(writing)
    print(f"  writer         {1e3 * write:8.3f} ms a frame = {100 * write * best_plain:.1f} % of the env's step "
          f"(rounds: {', '.join(f'{1e3 * x:.3f}' for x in writing)} ms)")
    if args.images:
        print(f"  video          {video_bytes / frames:8.0f} bytes a frame "
              f"({video_bytes / 1e6:.2f} MB for {frames} frames)")


if __name__ == "__main__":
    main()
