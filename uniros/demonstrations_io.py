"""Recorded episodes into a replay buffer: ``uniros train ID --demos DATASET``.

Reads a LeRobot dataset written by ``uniros record`` (:mod:`uniros.recording`; from the same env ID or its
Sim/Real twin), checks it against the env the model trains on (its observation features and action
shapes, finite values, actions inside the action space) and turns its episodes back into transitions
``(obs, next_obs, action, reward, terminated, truncated, info)``, the ones the scripted demonstrations
give (:func:`rl_environments.manipulation_scripted.fill_replay_buffer`), so an SB3 off-policy model's
``ReplayBuffer`` or ``HerReplayBuffer`` takes them the same way. Any fault is a
:class:`DemonstrationsError` with one line.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from uniros.lerobot_dataset import DatasetFormatError
from uniros.lerobot_dataset_reader import RecordedDataset, read_dataset

__all__ = ["DemonstrationsError", "Transition", "check_dataset", "fill_replay_buffer_from_dataset",
           "load_demonstrations"]


class DemonstrationsError(ValueError):
    """A dataset that cannot fill this model's replay buffer: the message names the dataset and the fault."""


@dataclass(frozen=True)
class Transition:
    """One step of a recorded episode, as :func:`~rl_environments.manipulation_scripted.run_episode` gives it."""

    obs: Any
    next_obs: Any
    action: np.ndarray
    reward: float
    terminated: bool
    truncated: bool
    info: dict[str, Any]


def _obs_keys(dataset: RecordedDataset, env: Any) -> dict[str, str]:
    from uniros.recording import dataset_features

    want, keys = dataset_features(env.observation_space, env.action_space)
    where = dataset.root
    meta = dataset.info.get("uniros")
    recorded = meta.get("env_id") if isinstance(meta, dict) else None
    have = dataset.features
    for name, ft in want.items():
        if name not in have:
            raise DemonstrationsError(f"{where}: no feature {name!r}: recorded from {recorded or 'another env'}, "
                                      f"not an env with these spaces")
        if list(have[name].get("shape", [])) != list(ft["shape"]):
            raise DemonstrationsError(f"{where}: {name} has shape {have[name].get('shape')}, the env's is "
                                      f"{ft['shape']} (recorded from {recorded or 'another env'})")
    return keys


def check_dataset(dataset: RecordedDataset, env: Any) -> dict[str, str]:
    """Refuse a dataset whose shapes, values or final observations do not fit ``env``; its observation keys."""
    keys = _obs_keys(dataset, env)
    where = dataset.root
    if not dataset.episodes:
        raise DemonstrationsError(f"{where}: no episodes")
    low, high = np.asarray(env.action_space.low), np.asarray(env.action_space.high)
    for ep in dataset.episodes:
        for name in [*keys, "action", "next.reward"]:
            if not np.all(np.isfinite(ep.frames[name].astype(np.float64))):
                raise DemonstrationsError(f"{where}: episode {ep.index}: {name} holds NaN or infinite values")
        act = ep.frames["action"]
        if np.any(act < low - 1e-6) or np.any(act > high + 1e-6):
            raise DemonstrationsError(f"{where}: episode {ep.index}: actions outside the env's action space "
                                      f"[{low.min()}, {high.max()}]")
        for name in keys:
            final = ep.final.get(name)
            if final is None or final.size != int(np.prod(ep.frames[name].shape[1:])) or not np.all(np.isfinite(final)):
                raise DemonstrationsError(f"{where}: episode {ep.index}: no valid final {name} (record it with "
                                          "uniros record)")
    return keys


def _observation(frames: dict[str, np.ndarray], final: dict[str, np.ndarray], keys: dict[str, str], t: int | None,
                 space: Any) -> Any:
    """The observation at frame ``t`` (``None``: after the last step), in the env's layout and dtypes."""
    parts = {}
    for name, key in keys.items():
        value = frames[name][t] if t is not None else final[name].reshape(frames[name].shape[1:])
        sub = space[key] if key else space
        parts[key] = np.asarray(value, dtype=sub.dtype)
    return parts.get("", parts)


def load_demonstrations(path: Path | str, env: Any) -> Iterator[list[Transition]]:
    """The episodes of the dataset at ``path`` as lists of transitions for ``env``'s model (checked first)."""
    try:
        dataset = read_dataset(path)
    except DatasetFormatError as exc:
        raise DemonstrationsError(str(exc)) from None
    keys = check_dataset(dataset, env)
    limit = getattr(getattr(env, "spec", None), "max_episode_steps", None)
    space = env.observation_space
    for ep in dataset.episodes:
        n = len(ep)
        success = ep.frames.get("next.success")
        episode = []
        for t in range(n):
            last = t == n - 1
            truncated = last and limit is not None and n >= int(limit)
            terminated = last and not truncated
            info = {"is_success": bool(success[t]) if success is not None else False}
            episode.append(Transition(
                obs=_observation(ep.frames, ep.final, keys, t, space),
                next_obs=_observation(ep.frames, ep.final, keys, None if last else t + 1, space),
                action=np.asarray(ep.frames["action"][t], np.float32), reward=float(ep.frames["next.reward"][t]),
                terminated=terminated, truncated=truncated, info=info))
        yield episode


def fill_replay_buffer_from_dataset(model: Any, path: Path | str, env: Any) -> dict[str, float]:
    """Add the recorded episodes at ``path`` to an SB3 off-policy model's replay buffer (``ReplayBuffer`` or
    ``HerReplayBuffer``), as the scripted demonstrations are added; ``env`` is one env with the model's spaces.

    Returns ``{"episodes", "transitions", "success_rate"}``.
    """
    buffer = getattr(model, "replay_buffer", None)
    if buffer is None:
        raise DemonstrationsError("the model has no replay buffer: --demos needs an off-policy algorithm")
    space = buffer.observation_space
    if any(len(getattr(s, "shape", ())) == 3 for s in getattr(space, "spaces", {"": space}).values()):
        raise DemonstrationsError("--demos fills state observations only; this model's observations have images")

    def stored(o: Any) -> Any:
        return {k: np.asarray(v)[None] for k, v in o.items()} if isinstance(o, dict) else np.asarray(o)[None]

    episodes = transitions = successes = 0
    for episode in load_demonstrations(path, env):
        for tr in episode:
            info = dict(tr.info)
            if tr.truncated and not tr.terminated:
                info["TimeLimit.truncated"] = True
                info["terminal_observation"] = tr.next_obs
            buffer.add(stored(tr.obs), stored(tr.next_obs), tr.action[None], np.array([tr.reward], np.float32),
                       np.array([tr.terminated or tr.truncated]), [info])
            transitions += 1
        episodes += 1
        successes += int(episode[-1].info["is_success"])
    return {"episodes": float(episodes), "transitions": float(transitions),
            "success_rate": successes / max(1, episodes)}


def check_dataset_for(path: Path | str, env_id: str) -> None:
    """Before a run is written: ``path`` is a recorded dataset (its ``meta/info.json`` reads) recorded from
    ``env_id`` when it says where it came from. The frames are checked against the env when they are loaded.

    Raises:
        DemonstrationsError: no dataset there, or one recorded from another ID.
    """
    from uniros.lerobot_dataset import DatasetFormatError
    from uniros.lerobot_dataset_reader import read_info

    root = Path(path)
    try:
        info = read_info(root)
    except DatasetFormatError as exc:
        raise DemonstrationsError(str(exc)) from None
    meta = info.get("uniros")
    recorded = meta.get("env_id") if isinstance(meta, dict) else None
    bare = env_id.rpartition(":")[2]
    if isinstance(recorded, str) and recorded.rpartition(":")[2] != bare:
        raise DemonstrationsError(f"{root}: recorded from {recorded[:100]!r}, not {env_id!r}: record the episodes "
                                  f"with uniros record {env_id}")
