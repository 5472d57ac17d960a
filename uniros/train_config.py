"""The training YAML: sb3_ros_support's and FRobs_RL's format, checked key by key.

Both forms are read: sb3_ros_support's flat mapping and FRobs_RL's ``model_params:`` wrapper. The
algorithm is the ``algorithm`` key, or the one ``<algo>_params`` block present (FRobs_RL files have
no ``algorithm`` key), or the trainer class's own. Every key is checked: an unknown or misspelt key
is an error naming the key and the nearest valid one, at every level (``eval_frq``,
``her_params.n_sampled_goals``, ``sac_params.learnig_rate``).
"""

from __future__ import annotations

import copy
import difflib
import logging
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from uniros.algorithms import (
    ALGORITHMS,
    algorithm_class,
    algorithm_keywords,
    is_off_policy,
    names_where,
    takes_action_noise,
    takes_sde,
)
from uniros.devices import check_device
from uniros.errors import TrainingConfigError, TrainingError

_log = logging.getLogger(__name__)

# A checkpoint prefix is part of file names inside the run folder: one plain name component.
_PLAIN_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+-]*$")
MAX_PREFIX_LENGTH = 64


# Top-level keys: (type, default). ``...`` as default: required.
_TOP: dict[str, tuple[Any, Any]] = {
    "algorithm": (str, None),
    "training_steps": (int, ...),
    "seed": (int, 0),
    "torch_threads": (int, 1),
    "n_envs": (int, 1),
    "pin_workers": (bool, False),
    "normalize": (bool, False),
    "eval_freq": (int, 1000),
    "eval_episodes": (int, 20),
    "stop_at_success": ((float, int), None),
    "env_kwargs": (dict, None),
    "video": (bool, True),
    "video_episodes": (int, 3),
    "progress_bar": (bool, True),
    "demonstrations": (int, 0),
    "demos": (str, None),
    "keep_checkpoints": (int, 3),
    "keep_replay_buffers": (int, 1),
    # sb3_ros_support / FRobs_RL
    "save_freq": (int, 1000),
    "save_prefix": (str, "model"),
    "trained_model_name": (str, "trained_model"),
    "save_replay_buffer": (bool, False),
    "load_model": (bool, False),
    "model_name": (str, None),
    "log_folder": (str, None),
    "log_interval": (int, 4),
    "reset_num_timesteps": (bool, False),
    "use_custom_policy": (bool, False),
    "policy_params": (dict, None),
    "use_action_noise": (bool, False),
    "action_noise_type": (str, "normal"),
    "action_noise": (dict, None),
    "use_sde": (bool, False),
    "sde_params": (dict, None),
    "use_HER": (bool, False),
    "her_params": (dict, None),
    "use_wandb": (bool, False),
    "wandb_params": (dict, None),
}
_NESTED: dict[str, set[str]] = {
    "her_params": {"n_sampled_goal", "goal_selection_strategy", "copy_info_dict", "online_sampling",
                   "max_episode_length"},
    "policy_params": {"net_arch", "activation_fn", "features_extractor_class", "optimizer_class", "log_std_init",
                      "ortho_init", "n_critics", "share_features_extractor", "normalize_images", "use_expln",
                      "squash_output", "full_std", "clip_mean", "optimizer_kwargs", "features_extractor_kwargs"},
    "action_noise": {"mean", "sigma", "theta", "dt"},
    "sde_params": {"sde_sample_freq", "use_sde_at_warmup"},
}
# Keyword arguments of the SB3 classes that the YAML must not set itself (uniros sets them).
_MANAGED = {"self", "policy", "env", "replay_buffer_class", "replay_buffer_kwargs", "action_noise", "policy_kwargs",
            "tensorboard_log", "verbose", "_init_setup_model", "use_sde", "sde_sample_freq",
            "use_sde_at_warmup"}


@dataclass
class TrainingConfig:
    """A parsed training YAML.

    Attributes:
        algorithm: a name of :data:`uniros.algorithms.ALGOS` (``sac``, ``td3``, ``tqc``, ``ppo``, ...).
        training_steps: env steps to train for (in total: a resumed run trains the rest).
        algo_params: keyword arguments of the SB3 algorithm (``<algo>_params``); its ``device``
            (``auto``, ``cpu``, ``cuda``, ``cuda:N``; :mod:`uniros.devices`) is resolved when the
            model is built or loaded.
        use_her, her_params: HER replay (goal envs, off-policy algorithms).
        policy_params: ``net_arch``, ``activation_fn`` (by name), ... when ``use_custom_policy``.
        action_noise: ``{"mean", "sigma"}`` action noise when ``use_action_noise``
            (``action_noise_type``: ``normal`` or ``ornstein``).
        use_sde, sde_params: generalised state-dependent exploration (SAC, PPO, A2C).
        env_kwargs: keyword arguments for ``uniros.make``.
        n_envs: envs trained on at once, in one batched vector env (all their robots in one
            simulation node, one request per step: :class:`uniros.vec_env.BatchedVecEnv`). Each
            vector step is ``n_envs`` env steps; ``train_freq`` and ``gradient_steps`` count vector
            steps, as in SB3.
        pin_workers: with ``n_envs`` > 1, each worker process of the vector env ``uniros train`` (and
            :func:`uniros.training.train`) builds on a core of its own (for a machine the run has to
            itself; see docs/vector_envs.md). The trainer classes train the env they are given.
        eval_freq, eval_episodes: evaluation schedule (env steps; 0 disables evaluation). With
            ``n_envs`` N, every ``eval_freq // N`` vector steps.
        stop_at_success: stop once this eval success rate is reached (``None``: never).
        normalize: normalise observations with ``VecNormalize``; evaluation uses the training
            statistics, frozen.
        seed: seed of the algorithm and of the training env's first reset.
        torch_threads: torch CPU threads (1 is fastest for these small networks).
        save_freq: env steps between checkpoints (model, replay buffer, normalisation); 0: none.
            With ``n_envs`` N, every ``save_freq // N`` vector steps.
        save_prefix, trained_model_name, save_replay_buffer, load_model, model_name, log_folder,
            log_interval, reset_num_timesteps: as in sb3_ros_support (see docs/training.md).
        keep_checkpoints: model checkpoints kept (the newest; with their normalisation
            statistics); 0 keeps every one (SB3's ``CheckpointCallback``).
        keep_replay_buffers: of those, how many newest keep their replay buffer (the large part);
            0 keeps it with every kept checkpoint.
        demonstrations: scripted episodes put into the replay buffer before learning (push and
            pick-and-place: :mod:`rl_environments.manipulation_scripted`); 0: none.
        video, video_episodes: record an MP4 of the best model after a run (real-time speed).
        progress_bar: show SB3's progress bar (rate and ETA).
    """

    algorithm: str = "sac"
    training_steps: int = 10_000
    algo_params: dict[str, Any] = field(default_factory=dict)
    use_her: bool = False
    her_params: dict[str, Any] = field(default_factory=dict)
    policy_params: dict[str, Any] | None = None
    action_noise: dict[str, float] | None = None
    action_noise_type: str = "normal"
    use_sde: bool = False
    sde_params: dict[str, Any] = field(default_factory=dict)
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    eval_freq: int = 1000
    eval_episodes: int = 20
    stop_at_success: float | None = None
    normalize: bool = False
    seed: int | None = 0
    torch_threads: int = 1
    n_envs: int = 1
    pin_workers: bool = False
    save_freq: int = 1000
    save_prefix: str = "model"
    trained_model_name: str = "trained_model"
    save_replay_buffer: bool = False
    load_model: bool = False
    model_name: str | None = None
    log_folder: str | None = None
    log_interval: int = 4
    reset_num_timesteps: bool = False
    keep_checkpoints: int = 3
    keep_replay_buffers: int = 1
    demonstrations: int = 0
    #: A recorded dataset (``uniros record``) whose episodes go into the replay buffer before learning.
    demos: str | None = None
    video: bool = True
    video_episodes: int = 3
    progress_bar: bool = True
    source: str = "<defaults>"

    @property
    def device(self) -> str:
        """The device choice (``<algo>_params.device``; ``auto`` when the YAML sets none)."""
        return str(self.algo_params.get("device", "auto"))

    def to_dict(self) -> dict[str, Any]:
        """The resolved config as a YAML mapping that :func:`parse_training_config` reads back."""
        params = copy.deepcopy(self.algo_params)
        if isinstance(params.get("train_freq"), tuple):
            freq, unit = params["train_freq"]
            params["train_freq"] = {"freq": freq, "unit": unit}
        out: dict[str, Any] = {
            "algorithm": self.algorithm, "training_steps": self.training_steps, "seed": self.seed,
            "torch_threads": self.torch_threads, "n_envs": self.n_envs, "pin_workers": self.pin_workers,
            "normalize": self.normalize,
            "eval_freq": self.eval_freq,
            "eval_episodes": self.eval_episodes, "stop_at_success": self.stop_at_success,
            "save_freq": self.save_freq, "save_prefix": self.save_prefix,
            "keep_checkpoints": self.keep_checkpoints, "keep_replay_buffers": self.keep_replay_buffers,
            "demonstrations": self.demonstrations, "demos": self.demos,
            "trained_model_name": self.trained_model_name, "save_replay_buffer": self.save_replay_buffer,
            "log_interval": self.log_interval, "reset_num_timesteps": self.reset_num_timesteps,
            "use_HER": self.use_her, "her_params": dict(self.her_params),
            "use_custom_policy": self.policy_params is not None, "policy_params": self.policy_params,
            "use_action_noise": self.action_noise is not None, "action_noise_type": self.action_noise_type,
            "action_noise": self.action_noise, "use_sde": self.use_sde, "sde_params": dict(self.sde_params),
            "video": self.video, "video_episodes": self.video_episodes, "progress_bar": self.progress_bar,
            f"{self.algorithm}_params": params, "env_kwargs": copy.deepcopy(self.env_kwargs),
        }
        return {"model_params": {k: v for k, v in out.items() if v is not None}}


def _nearest(key: str, valid: Any) -> str:
    close = difflib.get_close_matches(key, sorted(valid), n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else f"; valid keys: {sorted(valid)}"


def _check_keys(mapping: Mapping[str, Any], valid: Any, where: str) -> None:
    for key in mapping:
        if key not in valid:
            raise TrainingConfigError(f"{where}: unknown key {key!r}{_nearest(str(key), valid)}")


def _pin_workers(data: Mapping[str, Any], source: str) -> bool:
    """The ``pin_workers`` key: a bool, and not an env keyword (each env would get it, the evaluation
    env too)."""
    env_kwargs = data.get("env_kwargs")
    if isinstance(env_kwargs, Mapping) and "pin_workers" in env_kwargs:
        raise TrainingConfigError(f"{source}: pin_workers is a key of the run, not of each env: move it out of "
                                  "env_kwargs (pin_workers: true beside n_envs)")
    value = _typed(data, "pin_workers", source)
    if not isinstance(value, bool):
        raise TrainingConfigError(f"{source}: pin_workers must be true or false, got {value!r}")
    return value


def _typed(mapping: Mapping[str, Any], key: str, source: str, stand_in: Any = None) -> Any:
    kind, default = _TOP[key]
    if key not in mapping and stand_in is not None:
        return stand_in
    if key not in mapping:
        if default is ...:
            hint = " (or pass --steps)" if key == "training_steps" else ""
            raise TrainingConfigError(f"{source}: missing key {key!r}{hint}")
        return copy.deepcopy(default)
    value = mapping[key]
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    bad_bool = isinstance(value, bool) and kind is not bool and kind != (float, int)
    if value is not None and (not isinstance(value, kind) or bad_bool):
        names = kind.__name__ if isinstance(kind, type) else " or ".join(k.__name__ for k in kind)
        raise TrainingConfigError(f"{source}: key {key!r} must be {names}, got {value!r}")
    return value


def algo_keywords(algorithm: str) -> set[str]:
    """The keyword arguments an ``<algo>_params`` block may set (the SB3 class's, minus uniros' own)."""
    return algorithm_keywords(algorithm_class(algorithm)) - _MANAGED


# Hyperparameters whose type a YAML gets wrong most often, checked before SB3 sees them (SB3 would
# fail later with a traceback, or on resume not at all). Schedules are not expressible in YAML.
_NUMBER_PARAMS = ("learning_rate", "gamma", "tau", "gae_lambda", "vf_coef", "max_grad_norm", "clip_range",
                  "exploration_fraction", "exploration_initial_eps", "exploration_final_eps", "target_kl")
_INT_PARAMS = ("buffer_size", "learning_starts", "batch_size", "gradient_steps", "n_steps", "n_epochs",
               "target_update_interval", "policy_delay")


def _check_param_types(params: Mapping[str, Any], where: str) -> None:
    for key in _NUMBER_PARAMS:
        value = params.get(key)
        if key in params and (isinstance(value, bool) or not isinstance(value, (int, float))):
            raise TrainingConfigError(f"{where}.{key} must be a number, got {value!r}")
    for key in _INT_PARAMS:
        value = params.get(key)
        if key in params and (isinstance(value, bool) or not isinstance(value, int)):
            if key == "gradient_steps" and value is None:
                continue
            raise TrainingConfigError(f"{where}.{key} must be an integer, got {value!r}")
    ent = params.get("ent_coef")
    if "ent_coef" in params and not (isinstance(ent, (int, float)) and not isinstance(ent, bool)) and not (
            isinstance(ent, str) and re.fullmatch(r"auto(_[0-9.eE+-]+)?", ent)):
        raise TrainingConfigError(f"{where}.ent_coef must be a number, 'auto' or 'auto_<initial value>', "
                                  f"got {ent!r}")


def check_save_prefix(prefix: str, where: str = "save_prefix") -> str:
    """``prefix`` if it is a plain file-name part (checkpoints stay inside their folder).

    Raises:
        TrainingConfigError: a path (``../x``, ``/abs``, ``a/b``), an empty, hidden or overlong name.
    """
    if not isinstance(prefix, str) or not _PLAIN_NAME.match(prefix) or len(prefix) > MAX_PREFIX_LENGTH:
        raise TrainingConfigError(
            f"{where} {prefix!r} must be a plain name of at most {MAX_PREFIX_LENGTH} letters, digits, '.', '_', "
            "'+' or '-', not starting with '.' (checkpoints are written inside the run's checkpoints/ folder)")
    return prefix


def parse_training_config(
    data: Mapping[str, Any], source: str = "<mapping>", *, algorithm: str | None = None, steps: int | None = None
) -> TrainingConfig:
    """Check and convert a training YAML mapping.

    Args:
        algorithm: the algorithm the caller trains (a trainer class's); the YAML must agree.
        steps: stands in for a missing ``training_steps`` (``uniros train --steps``).

    Raises:
        TrainingConfigError: an unknown, misspelt, missing or mistyped key, an unknown algorithm, or
            a config for another algorithm.
    """
    if not isinstance(data, Mapping):
        raise TrainingConfigError(f"{source}: expected a mapping, got {type(data).__name__}")
    if "model_params" in data:
        _check_keys(data, {"model_params"}, source)
        data = data["model_params"]
        if not isinstance(data, Mapping):
            raise TrainingConfigError(f"{source}: 'model_params' must be a mapping")
    blocks = [a for a in ALGORITHMS if f"{a}_params" in data]
    _check_keys(data, set(_TOP) | {f"{a}_params" for a in ALGORITHMS}, source)
    named = _typed(data, "algorithm", source)
    algo = (named or (blocks[0] if len(blocks) == 1 else None) or algorithm or "sac").lower()
    if algo not in ALGORITHMS:
        raise TrainingConfigError(f"{source}: algorithm {algo!r} is not one of {list(ALGORITHMS)}"
                                  + _nearest(algo, ALGORITHMS).replace("; valid keys:", "; algorithms:"))
    try:
        algorithm_class(algo)
    except TrainingConfigError as exc:
        raise TrainingConfigError(f"{source}: {exc}") from None
    if algorithm is not None and algo != algorithm:
        raise TrainingConfigError(
            f"{source} is a {algo.upper()} config ({'algorithm: ' + algo if named else algo + '_params'}), "
            f"but it was given to {algorithm.upper()}; use the {algo.upper()} class or a {algorithm} config"
        )
    others = [b for b in blocks if b != algo]
    if others:
        raise TrainingConfigError(
            f"{source}: has {others[0]}_params but the algorithm is {algo!r}; "
            f"rename the block to {algo}_params or set algorithm: {others[0]}"
        )
    params = data.get(f"{algo}_params") or {}
    if not isinstance(params, Mapping):
        raise TrainingConfigError(f"{source}: key '{algo}_params' must be dict, got {params!r}")
    params = dict(params)
    _check_keys(params, algo_keywords(algo), f"{source}: {algo}_params")
    _check_param_types(params, f"{source}: {algo}_params")
    if "device" in params:
        params["device"] = check_device(params["device"], f"{source}: {algo}_params.device")
    if isinstance(params.get("train_freq"), Mapping):
        tf = params["train_freq"]
        _check_keys(tf, {"freq", "unit"}, f"{source}: {algo}_params.train_freq")
        params["train_freq"] = (int(tf.get("freq", 1)), str(tf.get("unit", "step")))
    seed = _typed(data, "seed", source)
    if "seed" in params:  # sb3_ros_support keeps the seed in <algo>_params
        seed = params.pop("seed")
    nested = {}
    for key, valid in _NESTED.items():
        block = _typed(data, key, source) or {}
        _check_keys(block, valid, f"{source}: {key}")
        nested[key] = dict(block)
    noise = None
    if _typed(data, "use_action_noise", source) and takes_action_noise(algo):
        noise = {"mean": 0.0, "sigma": 0.1, **nested["action_noise"]}
    noise_type = _typed(data, "action_noise_type", source).lower()
    if noise_type not in ("normal", "ornstein"):
        raise TrainingConfigError(f"{source}: action_noise_type {noise_type!r} is not 'normal' or 'ornstein'")
    policy = None
    if _typed(data, "use_custom_policy", source):
        if "policy_params" not in data:
            raise TrainingConfigError(f"{source}: missing key 'policy_params' (use_custom_policy is true)")
        policy = nested["policy_params"]
    elif "policy_params" in data:
        if "use_custom_policy" not in data:  # policy_params alone: the writer meant them to be used
            raise TrainingConfigError(
                f"{source}: policy_params is given without use_custom_policy: true, so it would be ignored: add "
                "use_custom_policy: true to use it, or remove it")
        # MultiROS/FRobs_RL files keep policy_params beside use_custom_policy: false: say it is not used
        _log.warning("%s: use_custom_policy is false: policy_params is not used (the algorithm's default policy)",
                     source)
    use_her = bool(_typed(data, "use_HER", source))
    if use_her and not is_off_policy(algo):
        raise TrainingConfigError(
            f"{source}: use_HER needs an off-policy algorithm ({', '.join(names_where(is_off_policy))}), not {algo!r}"
        )
    her = nested["her_params"]
    for obsolete in ("online_sampling", "max_episode_length"):
        her.pop(obsolete, None)  # read by old SB3 versions, gone since SB3 1.7
    use_sde = bool(_typed(data, "use_sde", source))
    if use_sde and not takes_sde(algo):
        raise TrainingConfigError(f"{source}: use_sde works with {', '.join(names_where(takes_sde))}, not {algo!r}")
    demonstrations = _typed(data, "demonstrations", source)
    if demonstrations is None or demonstrations < 0:
        raise TrainingConfigError(f"{source}: demonstrations must be 0 (none) or a number of episodes, "
                                  f"got {demonstrations}")
    if demonstrations and not is_off_policy(algo):
        raise TrainingConfigError(f"{source}: demonstrations go into a replay buffer: they need an off-policy "
                                  f"algorithm ({', '.join(names_where(is_off_policy))}), not {algo!r}")
    demos = _typed(data, "demos", source)
    if demos is not None and not is_off_policy(algo):
        raise TrainingConfigError(f"{source}: demos go into a replay buffer: they need an off-policy "
                                  f"algorithm ({', '.join(names_where(is_off_policy))}), not {algo!r}")
    keep = {k: _typed(data, k, source) for k in ("keep_checkpoints", "keep_replay_buffers")}
    for key, value in keep.items():
        if value is None or value < 0:
            raise TrainingConfigError(f"{source}: {key} must be 0 (keep all) or positive, got {value}")
    save_prefix = check_save_prefix(_typed(data, "save_prefix", source), f"{source}: save_prefix")
    stop = _typed(data, "stop_at_success", source)
    positive = {k: _typed(data, k, source, steps if k == "training_steps" else None)
                for k in ("training_steps", "eval_episodes", "log_interval", "n_envs")}
    for key, value in positive.items():
        if value is None or value < 1:
            raise TrainingConfigError(f"{source}: {key} must be at least 1, got {value}")
    for key in ("eval_freq", "save_freq"):
        value = _typed(data, key, source)
        if value is None or value < 0:
            raise TrainingConfigError(f"{source}: {key} must be 0 (off) or positive, got {value}")
    return TrainingConfig(
        algorithm=algo,
        training_steps=positive["training_steps"],
        algo_params=params,
        use_her=use_her,
        her_params=her,
        policy_params=policy,
        action_noise=noise,
        action_noise_type=noise_type,
        use_sde=use_sde,
        sde_params=nested["sde_params"],
        env_kwargs=dict(_typed(data, "env_kwargs", source) or {}),
        eval_freq=_typed(data, "eval_freq", source),
        eval_episodes=positive["eval_episodes"],
        stop_at_success=None if stop is None else float(stop),
        normalize=_typed(data, "normalize", source),
        seed=seed,
        torch_threads=_typed(data, "torch_threads", source),
        n_envs=positive["n_envs"],
        pin_workers=_pin_workers(data, source),
        save_freq=_typed(data, "save_freq", source),
        save_prefix=save_prefix,
        keep_checkpoints=keep["keep_checkpoints"],
        keep_replay_buffers=keep["keep_replay_buffers"],
        demonstrations=demonstrations, demos=demos,
        trained_model_name=_typed(data, "trained_model_name", source),
        save_replay_buffer=_typed(data, "save_replay_buffer", source),
        load_model=_typed(data, "load_model", source),
        model_name=_typed(data, "model_name", source),
        log_folder=_typed(data, "log_folder", source),
        log_interval=positive["log_interval"],
        reset_num_timesteps=_typed(data, "reset_num_timesteps", source),
        video=_typed(data, "video", source),
        video_episodes=_typed(data, "video_episodes", source),
        progress_bar=_typed(data, "progress_bar", source),
        source=source,
    )


def load_training_config(path: str | Path, *, algorithm: str | None = None, steps: int | None = None) -> TrainingConfig:
    """Load a training YAML file (see :func:`parse_training_config`; ``steps`` stands in for a
    missing ``training_steps``)."""
    path = Path(path)
    if not path.is_file():
        raise TrainingConfigError(f"training config {str(path)!r} not found")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise TrainingConfigError(f"{path}: not valid YAML: {exc}") from exc
    return parse_training_config(data, str(path), algorithm=algorithm, steps=steps)


def shipped_config_ids() -> list[str]:
    """Env IDs with a training config: shipped in ``rl_environments.config.training``, or derived from
    their task for an arm file's IDs (:func:`arm_task_config`)."""
    from rl_environments.arm_registry import arm_env_ids, registered_arms

    root = resources.files("rl_environments.config").joinpath("training")
    ids = {p.name[: -len(".yaml")] for p in root.iterdir() if p.name.endswith(".yaml")}
    return sorted(ids.union(*(arm_env_ids(spec) for spec in registered_arms().values())))


def _merge(base: dict[str, Any], over: Mapping[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for key, value in over.items():
        out[key] = _merge(out[key], value) if isinstance(value, Mapping) and isinstance(out.get(key), dict) else value
    return out


def arm_task_config(env_id: str) -> TrainingConfig | None:
    """An arm file's ID's training config: its task's (``config/training/tasks/<task>.yaml``) with the
    arm file's ``training: {<task>: {...}}`` merged over ``model_params``; None for other IDs."""
    from rl_environments.arm_registry import arm_env_ids, registered_arms

    for spec in registered_arms().values():
        found = arm_env_ids(spec).get(env_id)
        if found is None:
            continue
        task = found[0]
        path = Path(str(resources.files("rl_environments.config").joinpath("training", "tasks", f"{task}.yaml")))
        data = yaml.safe_load(path.read_text())
        data["model_params"] = _merge(data["model_params"], spec.training.get(task, {}))
        source = f"{path} with {spec.path}'s training.{task}" if task in spec.training else str(path)
        return parse_training_config(data, source)
    return None


def _simulated_twin(env_id: str) -> str | None:
    """The simulated twin of a Real ID of rl_environments, if ``env_id`` is one."""
    import rl_environments

    return next((sim for sim, real in rl_environments.SIM_TO_REAL.items() if real == env_id), None)


def default_config_for(env_id: str) -> TrainingConfig:
    """The training config uniros ships for ``env_id``: for an arm file's ID its task's
    (``config/training/tasks/<task>.yaml``, :func:`arm_task_config`), else ``config/training/<env_id>.yaml``
    (a Real ID has none: the error names its simulated twin to train)."""
    bare = env_id.rpartition(":")[2]
    candidate = resources.files("rl_environments.config").joinpath("training", f"{bare}.yaml")
    derived = None if candidate.is_file() else arm_task_config(bare)
    if derived is not None:
        return derived
    if not candidate.is_file():
        twin = _simulated_twin(bare)
        if twin is not None:
            raise TrainingConfigError(
                f"no shipped training config for {env_id!r}: it drives a real robot. Train its simulated twin "
                f"({twin}) and run the model here with `uniros eval {bare} MODEL`, or pass --config FILE")
        raise TrainingConfigError(
            f"no shipped training config for {env_id!r} (`uniros list` marks the IDs that have one). "
            "Pass --config FILE")
    return load_training_config(Path(str(candidate)))


def save_training_config(config: TrainingConfig, path: Path) -> None:
    """Write the resolved config (every key, defaults filled in) as YAML."""
    header = f"# resolved training config (from {config.source})\n"
    path.write_text(header + yaml.safe_dump(config.to_dict(), sort_keys=False))


__all__ = [
    "ALGORITHMS",
    "TrainingConfig",
    "TrainingConfigError",
    "TrainingError",
    "algo_keywords",
    "check_save_prefix",
    "arm_task_config",
    "default_config_for",
    "load_training_config",
    "parse_training_config",
    "save_training_config",
    "shipped_config_ids",
]
