"""What a run leaves for people: evaluations.csv, the learning-curve plot and the evaluation video."""

from __future__ import annotations

import csv
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

EVAL_FIELDS = ("steps", "train_seconds", "success_rate", "episodes", "mean_return", "std_return", "mean_length")


_COUNT_FIELDS = frozenset({"steps", "episodes"})  # whole numbers: written as 150, never 150.0


def read_evaluations(path: Path) -> list[dict[str, float]]:
    """Rows of ``evaluations.csv`` (empty when the file does not exist); counts as ``int``."""
    if not path.is_file():
        return []
    with open(path, newline="") as f:
        return [{k: int(float(v)) if k in _COUNT_FIELDS else float(v) for k, v in row.items() if v not in ("", None)}
                for row in csv.DictReader(f)]


def _cell(key: str, value: Any) -> str:
    """One number of ``evaluations.csv``, in one format whether it was just measured or read back
    (a resumed run rewrites the file): counts as integers, the rest as Python's shortest float."""
    if value is None or value == "":
        return ""
    return str(int(value)) if key in _COUNT_FIELDS else repr(float(value))


def write_evaluations(path: Path, rows: Sequence[dict[str, float]]) -> None:
    """Write ``evaluations.csv`` (atomically)."""
    from uniros.run_dir import atomic_write

    def write(tmp: Path) -> None:
        with open(tmp, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=EVAL_FIELDS, extrasaction="ignore")
            writer.writeheader()
            writer.writerows({k: _cell(k, v) for k, v in row.items() if k in EVAL_FIELDS} for row in rows)

    atomic_write(path, write)


def _monitor_rows(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cumulative env steps, returns and successes of the training episodes in a Monitor CSV."""
    steps, returns, success = [], [], []
    if path.is_file():
        with open(path, newline="") as f:
            lines = [line for line in f if not line.startswith("#")]
        total = 0
        for row in csv.DictReader(lines):
            try:
                length, ret = int(float(row["l"])), float(row["r"])
                flag = row.get("is_success") or "nan"  # SB3's Monitor writes True/False
                ok = 1.0 if flag == "True" else 0.0 if flag == "False" else float(flag)
            except (KeyError, ValueError):
                continue
            total += length
            returns.append(ret)
            success.append(ok)
            steps.append(total)
    return np.asarray(steps, float), np.asarray(returns, float), np.asarray(success, float)


def plot_learning_curve(evaluations: Sequence[dict[str, float]], path: Path, *, title: str = "",
                        monitor_csv: Path | None = None) -> Any:
    """Success rate and return against env steps, evaluation points marked; saved as a PNG.

    Returns the matplotlib figure (closed: its data stays readable).
    """
    os.environ.setdefault("MPLBACKEND", "Agg")
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    fig, (ax_s, ax_r) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    steps, returns, success = _monitor_rows(monitor_csv) if monitor_csv is not None else ([], [], [])
    window = 20
    if len(steps) >= 1:
        kernel = np.ones(min(window, len(steps))) / min(window, len(steps))
        trailing = steps[len(kernel) - 1:]  # the mean of the last episodes at each point (no zero padding)
        if np.isfinite(success).any():
            ax_s.plot(trailing, np.convolve(np.nan_to_num(success), kernel, mode="valid"), color="0.6",
                      lw=1, label=f"training episodes (mean of {len(kernel)})")
        ax_r.plot(trailing, np.convolve(returns, kernel, mode="valid"), color="0.6", lw=1,
                  label=f"training episodes (mean of {len(kernel)})")
    if evaluations:
        e_steps = [row["steps"] for row in evaluations]
        ax_s.plot(e_steps, [row["success_rate"] for row in evaluations], "o-", color="C0", label="evaluation",
                  gid="eval_success")
        ax_r.plot(e_steps, [row["mean_return"] for row in evaluations], "o-", color="C1", label="evaluation",
                  gid="eval_return")
    ax_s.set_ylabel("success rate")
    ax_s.set_ylim(-0.05, 1.05)
    ax_r.set_ylabel("episode return")
    ax_r.set_xlabel("env steps")
    for ax in (ax_s, ax_r):
        ax.grid(alpha=0.3)
        if ax.get_lines():
            ax.legend(loc="lower right", fontsize=8)
    if title:
        ax_s.set_title(title)
    fig.tight_layout()
    from uniros.run_dir import atomic_write

    atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=100, format="png"))
    plt.close(fig)
    return fig


def step_seconds(env: Any) -> float | None:
    """Robot time per env step, measured from the env's simulation clock around one step (``None``
    for an env without ``sim_time``); the env must have been reset."""
    base = getattr(env, "unwrapped", env)
    try:
        return float(base.sim_time)
    except (AttributeError, TypeError, ValueError):
        return None


def record_video(model: Any, make_env: Any, path: Path, *, episodes: int = 3, normalizer: Any = None,
                 seed: int = 0, fps: float | None = None, hold_seconds: float = 0.5) -> int:
    """Record ``episodes`` deterministic episodes of ``model`` as an MP4 at real-time speed.

    ``make_env(render_mode="rgb_array")`` builds the env (rendered headless). One frame per env
    step, played at ``fps`` (default: the env's step rate, read from its simulation clock, so a
    second of video is a second of robot time; else ``metadata["render_fps"]``). Each episode's
    last frame is held ``hold_seconds`` so that its end can be seen. Returns the number of frames.
    """
    os.environ.setdefault("MUJOCO_GL", "egl")
    import imageio.v2 as imageio

    from uniros.run_dir import atomic_write

    env = make_env(render_mode="rgb_array")
    frames: list[Any] = []
    rate = fps
    try:
        for i in range(episodes):
            obs, _ = env.reset(seed=seed + i)
            frames.append(env.render())
            done = False
            while not done:
                policy_obs = obs if normalizer is None else normalizer.normalize_obs(obs)
                action, _ = model.predict(policy_obs, deterministic=True)
                before = step_seconds(env)
                obs, _, terminated, truncated, _ = env.step(action)
                after = step_seconds(env)
                if rate is None and before is not None and after is not None and after > before:
                    rate = 1.0 / (after - before)
                frames.append(env.render())
                done = terminated or truncated
            if rate is None:
                rate = float(getattr(env, "metadata", {}).get("render_fps") or 25)
            frames.extend([frames[-1]] * max(0, round(hold_seconds * rate)))
    finally:
        env.close()
    rate = rate or 25.0

    def write(tmp: Path) -> None:
        with imageio.get_writer(str(tmp), format="FFMPEG", fps=rate, codec="libx264", macro_block_size=1,
                                ffmpeg_log_level="error") as writer:
            for frame in frames:
                writer.append_data(np.asarray(frame))

    atomic_write(path, write)
    return len(frames)
