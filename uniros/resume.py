"""What ``uniros train --resume`` promises: the newest checkpoint that loads completely, and a
config it can honour.

* **Which checkpoint.** Every file of each checkpoint, newest first, is read before the run is
  rebuilt (:func:`uniros.checkpoints.check_checkpoint`): the model (parameters included), the
  ``VecNormalize`` statistics when observations are normalised, and the replay buffer of an
  off-policy algorithm. The first whose files all load is used; the ones skipped are named with
  the reason. When none is complete, the newest whose model and statistics load is used with an
  empty replay buffer, which fills for ``learning_starts`` steps (and takes the demonstrations
  again) before updates go on (older checkpoints keep no buffer by default: ``keep_replay_buffers``).
  Checkpoints found unusable are moved to ``checkpoints/unusable/`` so that retention never keeps
  them in place of good ones. The checkpoint used is named. When no model loads at all, the run
  starts again from step 0 under its name, and what the earlier attempt wrote (best model,
  evaluations, logs) is moved to ``earlier/<n>/`` in the run folder, never deleted.
* **Which edits.** The run's ``config.yaml`` may be edited between runs. Keys that schedule the run
  (``training_steps``, ``eval_freq``, ``save_freq``, ``keep_*``, ``video``, ...) take effect, and
  so do hyperparameters SB3 sets on a loaded model (``learning_rate``, ``batch_size``, ``gamma``,
  ``tau``, ``gradient_steps``, ``train_freq``, ``learning_starts``, ``target_update_interval``), and
  the ``device`` (``uniros train --resume RUN --device cpu`` moves a run; without it the run keeps
  the device choice its ``config.yaml`` records).
  Anything that would need another model, env or replay buffer (``algorithm``, ``env_kwargs``,
  ``n_envs``, ``normalize``, ``use_HER``/``her_params``, ``policy_params``, ``buffer_size``, the
  action noise, ...) is refused with a message naming the key: it would otherwise be ignored, or
  silently drop what the run has learnt (``normalize: false`` would drop the statistics).
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field
from typing import Any

from uniros.checkpoints import CheckedCheckpoint, check_checkpoint, latest_checkpoint, own_folder
from uniros.errors import RunDirError, TrainingConfigError
from uniros.train_config import TrainingConfig, parse_training_config

_logger = logging.getLogger(__name__)

# Hyperparameters a loaded SB3 model takes (SB3's ``load(path, **kwargs)`` sets them before it
# rebuilds its schedules and train frequency).
RESUMABLE_PARAMS = frozenset({"learning_rate", "batch_size", "gamma", "tau", "gradient_steps", "train_freq",
                              "learning_starts", "target_update_interval"})
# Top-level keys that schedule, log or report the run: they take effect when it resumes.
RESUMABLE_KEYS = frozenset({"training_steps", "seed", "torch_threads", "eval_freq", "eval_episodes", "stop_at_success",
                            "save_freq", "keep_checkpoints", "keep_replay_buffers", "log_interval", "video",
                            "video_episodes", "progress_bar", "trained_model_name", "save_replay_buffer",
                            "load_model", "model_name", "log_folder", "reset_num_timesteps", "use_wandb",
                            "wandb_params", "pin_workers"})


def resume_overrides(started: TrainingConfig, now: TrainingConfig) -> dict[str, Any]:
    """The hyperparameters to set on the loaded model for the edits between ``started`` (the config
    the run started with) and ``now`` (its ``config.yaml`` today).

    Raises:
        TrainingConfigError: an edit the resumed run cannot honour (the message names the key and
            says what to do).
    """
    before, after = _flat(started), _flat(now)
    params = f"{now.algorithm}_params"
    for key in sorted(set(before) | set(after)):
        if before.get(key) == after.get(key) or key in RESUMABLE_KEYS:
            continue
        name = key.removeprefix("algo_params.")
        if key.startswith("algo_params.") and name in RESUMABLE_PARAMS:
            continue
        shown = f"{params}.{name}" if key.startswith("algo_params.") else key
        raise TrainingConfigError(
            f"{now.source}: {shown} was {before.get(key)!r} when the run started and is {after.get(key)!r} now; a "
            "resumed run keeps its model, env and replay buffer, so it cannot take this edit: put it back, or "
            f"start a new run with the edited config (uniros train ID --config {now.source})")
    return {k: now.algo_params[k] for k in RESUMABLE_PARAMS
            if k in now.algo_params and now.algo_params.get(k) != started.algo_params.get(k)}


# env_kwargs that choose how the simulation node runs or is reached, not the task: free to change.
NODE_KWARGS = frozenset({"sim_mode", "transport", "gui", "sim_node_name", "timeout_sec"})


def _flat(config: TrainingConfig) -> dict[str, Any]:
    data = dict(config.to_dict()["model_params"])
    params = dict(data.pop(f"{config.algorithm}_params", {}) or {})
    params.pop("device", None)  # where the model computes, not what it is: --device may move a resumed run
    data["env_kwargs"] = {k: v for k, v in (data.get("env_kwargs") or {}).items() if k not in NODE_KWARGS}
    flat = {k: v for k, v in data.items()}
    flat.update({f"algo_params.{k}": v for k, v in params.items()})
    return flat


def started_config(meta: dict[str, Any], source: str) -> TrainingConfig | None:
    """The config a run started with (kept in its ``run.json``), or ``None`` for older runs."""
    data = meta.get("started_with")
    if not isinstance(data, dict):
        return None
    return parse_training_config({"model_params": data}, f"{source} (run.json: started_with)")


@dataclass
class CheckpointChoice:
    """The checkpoint a resumed run starts from, and what was skipped on the way."""

    chosen: CheckedCheckpoint | None
    skipped: list[CheckedCheckpoint] = field(default_factory=list)

    @property
    def without_buffer(self) -> bool:
        """The chosen checkpoint's replay buffer is missing or unusable: the run refills it."""
        return self.chosen is not None and not self.chosen.complete

    def report(self) -> list[str]:
        """Lines saying which checkpoints were skipped and why, and what the run resumes from."""
        lines = [f"skipped checkpoint at {c.checkpoint.steps} steps: {'; '.join(c.problems)}" for c in self.skipped]
        if self.without_buffer:
            assert self.chosen is not None
            lines.append(f"resuming from {self.chosen.checkpoint.model.name} without a replay buffer "
                         f"({'; '.join(self.chosen.problems)}): it fills again for learning_starts steps before "
                         "updates go on")
        elif self.chosen is not None:
            ckpt = self.chosen.checkpoint
            with_files = [name for name, path in (("replay buffer", ckpt.replay_buffer),
                                                   ("normalisation statistics", ckpt.vecnormalize)) if path]
            lines.append(f"resuming from checkpoint {ckpt.model.name} ({ckpt.steps} steps"
                         + (f", with its {' and '.join(with_files)}" if with_files else "")
                         + f") in {ckpt.model.parent}")
        return lines


def choose_checkpoint(folder: Any, prefix: str, config: TrainingConfig, *, observation_space: Any,
                      action_space: Any, needs_buffer: bool) -> CheckpointChoice:
    """The newest checkpoint whose files all load, else the newest whose model and statistics do.

    Checkpoints found unusable are moved to ``<folder>/unusable/`` (kept for a look, out of the
    way of retention and of the next resume).
    """
    checked = []
    for ckpt in latest_checkpoint(folder, prefix):
        result = check_checkpoint(ckpt, observation_space=observation_space, action_space=action_space,
                                  algorithm=config.algorithm, needs_buffer=needs_buffer,
                                  needs_stats=config.normalize, n_envs=config.n_envs)
        checked.append(result)
        if result.complete:
            break
    chosen = next((c for c in checked if c.complete), None) or next((c for c in checked if c.model_usable), None)
    skipped = [c for c in checked if c is not chosen and (chosen is None or c.checkpoint.steps > chosen.checkpoint.steps
                                                            or not c.model_usable)]
    for bad in skipped:
        _set_aside(bad)
    return CheckpointChoice(chosen, skipped)


def _set_aside(checked: CheckedCheckpoint) -> None:
    """Move an unusable checkpoint's files to ``unusable/`` next to them: renames within the run
    (a file that is a link moves as the link), never onto an earlier file of that name."""
    ckpt = checked.checkpoint
    folder = own_folder(ckpt.model.parent / "unusable")
    if os.path.lexists(folder) and not folder.is_dir():
        raise RunDirError(f"{folder} is not a folder: a resumed run moves unusable checkpoints there; remove it")
    folder.mkdir(exist_ok=True)
    for path in (ckpt.model, ckpt.replay_buffer, ckpt.vecnormalize):
        if path is not None and os.path.lexists(path):
            dest, n = folder / path.name, 1
            while os.path.lexists(dest):
                n += 1
                dest = folder / f"{path.name}.{n}"
            os.rename(path, dest)


__all__ = [
    "NODE_KWARGS",
    "RESUMABLE_KEYS",
    "RESUMABLE_PARAMS",
    "CheckpointChoice",
    "choose_checkpoint",
    "resume_overrides",
    "started_config",
]
