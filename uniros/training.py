"""Training and evaluating Stable-Baselines3 agents on uniros envs from one YAML file.

One trainer, not one wrapper per algorithm: the YAML (the format of sb3_ros_support and FRobs_RL,
optionally under a ``model_params:`` key) names the algorithm and its ``<algo>_params``; goal envs
get ``HerReplayBuffer`` when ``use_HER`` is true. Evaluation runs on a separate env instance
every ``eval_freq`` steps and reports the success rate (mean of the final ``info["is_success"]``).

Configs shipped with uniros sit in ``config/training/`` (installed as
``rl_environments.config.training``), one per env ID; see :func:`default_config_for`.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import yaml

_logger = logging.getLogger(__name__)

ALGORITHMS = ("sac", "td3", "ddpg", "ppo", "a2c", "dqn")
_OFF_POLICY = {"sac", "td3", "ddpg", "dqn"}


class TrainingConfigError(ValueError):
    """A training YAML is missing, malformed, or names an unknown algorithm or option."""


@dataclass
class TrainingConfig:
    """A parsed training YAML.

    Attributes:
        algorithm: ``sac``, ``td3``, ``ddpg``, ``ppo``, ``a2c`` or ``dqn``.
        training_steps: env steps to train for.
        algo_params: keyword arguments of the SB3 algorithm (``<algo>_params``).
        use_her, her_params: HER replay (goal envs, off-policy algorithms).
        policy_params: ``net_arch``, ``activation_fn`` (by name), when ``use_custom_policy``.
        action_noise: ``{"mean", "sigma"}`` Gaussian action noise when ``use_action_noise``.
        env_kwargs: keyword arguments for ``uniros.make``.
        eval_freq, eval_episodes: evaluation schedule.
        stop_at_success: stop once this eval success rate is reached (``None``: never).
        normalize: normalise observations with ``VecNormalize`` (as rl-zoo3 does for FetchReach);
            the evaluation env uses the training statistics, frozen.
        seed: seed of the algorithm and of the training env's first reset.
        torch_threads: torch CPU threads (1 is fastest for these small networks).
    """

    algorithm: str = "sac"
    training_steps: int = 10_000
    algo_params: dict[str, Any] = field(default_factory=dict)
    use_her: bool = False
    her_params: dict[str, Any] = field(default_factory=dict)
    policy_params: dict[str, Any] | None = None
    action_noise: dict[str, float] | None = None
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    eval_freq: int = 1000
    eval_episodes: int = 20
    stop_at_success: float | None = None
    normalize: bool = False
    seed: int | None = 0
    torch_threads: int = 1
    source: str = "<defaults>"


def _require(mapping: Mapping[str, Any], key: str, kind: Any, source: str, default: Any = ...) -> Any:
    if key not in mapping:
        if default is ...:
            raise TrainingConfigError(f"{source}: missing key {key!r}")
        return default
    value = mapping[key]
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if value is not None and not isinstance(value, kind):
        names = kind.__name__ if isinstance(kind, type) else " or ".join(k.__name__ for k in kind)
        raise TrainingConfigError(f"{source}: key {key!r} must be {names}, got {value!r}")
    return value


def parse_training_config(data: Mapping[str, Any], source: str = "<mapping>") -> TrainingConfig:
    """Check and convert a training YAML mapping.

    Raises:
        TrainingConfigError: a missing or mistyped key, or an unknown algorithm.
    """
    if not isinstance(data, Mapping):
        raise TrainingConfigError(f"{source}: expected a mapping, got {type(data).__name__}")
    if "model_params" in data:
        data = data["model_params"]
        if not isinstance(data, Mapping):
            raise TrainingConfigError(f"{source}: 'model_params' must be a mapping")
    algo = str(_require(data, "algorithm", str, source, "sac")).lower()
    if algo not in ALGORITHMS:
        raise TrainingConfigError(f"{source}: algorithm {algo!r} is not one of {ALGORITHMS}")
    params = _require(data, f"{algo}_params", dict, source, {}) or {}
    params = dict(params)
    if isinstance(params.get("train_freq"), Mapping):
        tf = params["train_freq"]
        params["train_freq"] = (int(tf.get("freq", 1)), str(tf.get("unit", "step")))
    noise = None
    if _require(data, "use_action_noise", bool, source, False):
        noise = dict(_require(data, "action_noise", dict, source, {"mean": 0.0, "sigma": 0.1}))
    policy = None
    if _require(data, "use_custom_policy", bool, source, False):
        policy = dict(_require(data, "policy_params", dict, source))
    use_her = bool(_require(data, "use_HER", bool, source, False))
    if use_her and algo not in _OFF_POLICY:
        raise TrainingConfigError(
            f"{source}: use_HER needs an off-policy algorithm (sac, td3, ddpg, dqn), not {algo!r}"
        )
    her = dict(_require(data, "her_params", dict, source, {}) or {})
    for obsolete in ("online_sampling", "max_episode_length"):
        her.pop(obsolete, None)  # read by old SB3 versions, gone since SB3 1.7
    stop = _require(data, "stop_at_success", (float, int), source, None)
    return TrainingConfig(
        algorithm=algo,
        training_steps=int(_require(data, "training_steps", int, source)),
        algo_params=params,
        use_her=use_her,
        her_params=her,
        policy_params=policy,
        action_noise=noise,
        env_kwargs=dict(_require(data, "env_kwargs", dict, source, {}) or {}),
        eval_freq=int(_require(data, "eval_freq", int, source, 1000)),
        eval_episodes=int(_require(data, "eval_episodes", int, source, 20)),
        stop_at_success=None if stop is None else float(stop),
        normalize=bool(_require(data, "normalize", bool, source, False)),
        seed=_require(data, "seed", int, source, 0),
        torch_threads=int(_require(data, "torch_threads", int, source, 1)),
        source=source,
    )


def load_training_config(path: str | Path) -> TrainingConfig:
    """Load a training YAML file (see :func:`parse_training_config`)."""
    path = Path(path)
    if not path.is_file():
        raise TrainingConfigError(f"training config {str(path)!r} not found")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise TrainingConfigError(f"{path}: not valid YAML: {exc}") from exc
    return parse_training_config(data, str(path))


def default_config_for(env_id: str) -> TrainingConfig:
    """The training config uniros ships for ``env_id`` (``config/training/<env_id>.yaml``)."""
    root = resources.files("rl_environments.config").joinpath("training")
    candidate = root.joinpath(f"{env_id}.yaml")
    if not candidate.is_file():
        shipped = sorted(p.name[: -len(".yaml")] for p in root.iterdir() if p.name.endswith(".yaml"))
        raise TrainingConfigError(f"no shipped training config for {env_id!r}; shipped: {shipped}. Pass --config FILE")
    return load_training_config(Path(str(candidate)))


# -- building ----------------------------------------------------------------------------------
def _gamma(config: TrainingConfig) -> float:
    return float(config.algo_params.get("gamma", 0.99))


def _activation(name: str) -> Any:
    import torch.nn as nn

    table = {"relu": nn.ReLU, "tanh": nn.Tanh, "elu": nn.ELU, "selu": nn.SELU, "leaky_relu": nn.LeakyReLU}
    try:
        return table[name.lower()]
    except KeyError:
        raise TrainingConfigError(f"activation_fn {name!r} is not one of {sorted(table)}") from None


def build_model(config: TrainingConfig, env: Any, *, verbose: int = 0) -> Any:
    """The SB3 model for ``config`` on ``env`` (a gymnasium env or a VecEnv)."""
    import stable_baselines3 as sb3
    import torch
    from gymnasium import spaces
    from stable_baselines3.common.noise import NormalActionNoise

    torch.set_num_threads(max(1, config.torch_threads))
    cls = {"sac": sb3.SAC, "td3": sb3.TD3, "ddpg": sb3.DDPG, "ppo": sb3.PPO, "a2c": sb3.A2C, "dqn": sb3.DQN}[
        config.algorithm
    ]
    kwargs: dict[str, Any] = dict(config.algo_params)
    kwargs.setdefault("seed", config.seed)
    kwargs.setdefault("device", "cpu")
    obs_space = env.observation_space
    policy = "MultiInputPolicy" if isinstance(obs_space, spaces.Dict) else "MlpPolicy"
    if config.use_her:
        if not isinstance(obs_space, spaces.Dict):
            raise TrainingConfigError(f"{config.source}: use_HER needs a goal env (Dict observation space)")
        kwargs["replay_buffer_class"] = sb3.HerReplayBuffer
        kwargs["replay_buffer_kwargs"] = {"n_sampled_goal": 4, "goal_selection_strategy": "future", **config.her_params}
    if config.policy_params:
        pk = dict(config.policy_params)
        if "activation_fn" in pk:
            pk["activation_fn"] = _activation(pk["activation_fn"])
        for unused in ("features_extractor_class", "optimizer_class"):
            pk.pop(unused, None)
        kwargs["policy_kwargs"] = pk
    if config.action_noise is not None and config.algorithm in ("td3", "ddpg", "sac"):
        n = env.action_space.shape[0]
        kwargs["action_noise"] = NormalActionNoise(
            mean=np.full(n, float(config.action_noise.get("mean", 0.0))),
            sigma=np.full(n, float(config.action_noise.get("sigma", 0.1))),
        )
    try:
        return cls(policy, env, verbose=verbose, **kwargs)
    except TypeError as exc:
        raise TrainingConfigError(f"{config.source}: {config.algorithm}_params: {exc}") from exc


def evaluate(
    model: Any, env: Any, episodes: int, *, seed: int | None = None, normalizer: Any = None
) -> dict[str, float]:
    """Run ``episodes`` deterministic episodes; success = the final ``info["is_success"]``.

    ``normalizer`` (a ``VecNormalize``) normalises observations as during training.
    """
    successes, returns, lengths = [], [], []
    for i in range(episodes):
        obs, info = env.reset(seed=None if seed is None or i > 0 else seed)
        done, total, steps = False, 0.0, 0
        while not done:
            policy_obs = obs if normalizer is None else normalizer.normalize_obs(obs)
            action, _ = model.predict(policy_obs, deterministic=True)
            obs, reward, terminated, truncated, info = env.step(action)
            total += float(reward)
            steps += 1
            done = terminated or truncated
        successes.append(float(bool(info.get("is_success", False))))
        returns.append(total)
        lengths.append(steps)
    return {
        "success_rate": float(np.mean(successes)),
        "mean_return": float(np.mean(returns)),
        "mean_length": float(np.mean(lengths)),
    }


@dataclass
class TrainingResult:
    """What :func:`train` measured.

    Attributes:
        evaluations: ``(env_steps, train_seconds, success_rate)`` per evaluation.
        steps_to_success: first env step count whose evaluation reached ``target`` (or None).
        seconds_to_success: training wall-clock (evaluation excluded) at that point.
        total_steps, train_seconds: what was run.
    """

    evaluations: list[tuple[int, float, float]]
    steps_to_success: int | None
    seconds_to_success: float | None
    total_steps: int
    train_seconds: float
    model: Any = None
    normalizer: Any = None


def train(
    env_id: str,
    config: TrainingConfig,
    *,
    target: float = 0.9,
    on_eval: Callable[[int, float, float], None] | None = None,
    save_path: str | Path | None = None,
    verbose: int = 0,
    make_env: Callable[[], Any] | None = None,
) -> TrainingResult:
    """Train on ``env_id`` with ``config``; evaluate every ``eval_freq`` steps on a second env.

    Args:
        target: success rate that counts as solved (for ``steps_to_success``).
        on_eval: ``callback(steps, train_seconds, success_rate)`` after each evaluation.
        save_path: where to save the final model (``.zip``), if given.
        make_env: build the train and eval envs with this instead of ``uniros.make`` (baselines).
    """
    from stable_baselines3.common.callbacks import BaseCallback

    import uniros

    def factory() -> Any:
        return make_env() if make_env is not None else uniros.make(env_id, **config.env_kwargs)

    env = factory()
    eval_env = factory()
    evaluations: list[tuple[int, float, float]] = []
    clock = {"train": 0.0, "since": time.perf_counter()}
    reached: dict[str, Any] = {"steps": None, "seconds": None}

    class _EvalCallback(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps % config.eval_freq != 0:
                return True
            clock["train"] += time.perf_counter() - clock["since"]
            seed = None if config.seed is None else config.seed + 10_000 + len(evaluations)
            stats = evaluate(self.model, eval_env, config.eval_episodes, seed=seed, normalizer=normalizer)
            rate = stats["success_rate"]
            evaluations.append((self.num_timesteps, clock["train"], rate))
            if on_eval is not None:
                on_eval(self.num_timesteps, clock["train"], rate)
            if rate >= target and reached["steps"] is None:
                reached.update(steps=self.num_timesteps, seconds=clock["train"])
            clock["since"] = time.perf_counter()
            return not (config.stop_at_success is not None and rate >= config.stop_at_success)

    normalizer = None
    try:
        env.reset(seed=config.seed)
        train_env: Any = env
        if config.normalize:
            from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

            train_env = normalizer = VecNormalize(DummyVecEnv([lambda: env]), gamma=_gamma(config), norm_reward=False)
            train_env.seed(config.seed)
        model = build_model(config, train_env, verbose=verbose)
        model.learn(total_timesteps=config.training_steps, callback=_EvalCallback())
        clock["train"] += time.perf_counter() - clock["since"]
        if save_path is not None:
            model.save(str(save_path))
            if normalizer is not None:
                normalizer.save(str(Path(save_path).with_suffix(".vecnormalize.pkl")))
        return TrainingResult(
            evaluations=evaluations,
            steps_to_success=reached["steps"],
            seconds_to_success=reached["seconds"],
            total_steps=int(model.num_timesteps),
            train_seconds=clock["train"],
            model=model,
            normalizer=normalizer,
        )
    finally:
        env.close()
        eval_env.close()
