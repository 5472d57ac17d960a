"""``BasicModel``: sb3_ros_support's and FRobs_RL's model wrapper, on uniros' one trainer.

The arguments and YAML keys mean what they meant there (see docs/training.md, "Trainer classes"):
``save_model_path`` holds the checkpoints (``<save_prefix>_<N>_steps.zip`` every ``save_freq``
steps, with the replay buffer and normalisation statistics) and the trained model
(``<trained_model_name>.zip``, a ``_dd_mm_YYYY_HH_MM_SS`` suffix when the name is taken);
``log_path + log_folder`` holds the TensorBoard and CSV logs (a free ``_N`` suffix when the folder
exists: logs are never overwritten); ``load_model`` + ``model_name`` continue a saved model (and
its replay buffer); ``reset_num_timesteps: False`` continues its step count.
"""

from __future__ import annotations

import logging
import time
from importlib import resources
from pathlib import Path
from typing import Any

from uniros.devices import check_device, resolve_device
from uniros.run_dir import load_replay_buffer, normalizer_path, save_model_with_stats, save_replay_buffer
from uniros.run_envs import fit_learning_starts, reports_success
from uniros.train_config import TrainingConfig, TrainingConfigError, TrainingError, load_training_config
from uniros.trainer import Paths, Session, load_model

_logger = logging.getLogger(__name__)


def _package_dir(pkg: str, what: str) -> Path:
    """A package's root: a ROS-style package (multiros' index) or an importable Python package."""
    import importlib.util

    try:
        from multiros.utils.ros_common import get_package_path

        return Path(get_package_path(pkg))
    except Exception:  # not a ROS-style package: try Python
        pass
    try:
        spec = importlib.util.find_spec(pkg)
    except (ImportError, ValueError):
        spec = None
    if spec is None or not spec.submodule_search_locations:
        instead = " or give the file itself as abs_config_path" if what == "config_file_pkg" else ""
        raise TrainingConfigError(
            f"{what}: package {pkg!r} not found, neither a ROS package nor an importable Python package: source "
            "the ROS workspace that installs it (AMENT_PREFIX_PATH), add the directory that holds it to "
            f"ROS_PACKAGE_PATH, or install it as a Python package{instead}")
    return Path(next(iter(spec.submodule_search_locations)))


def resolve_config_path(algo: str, goal: bool, config_file_pkg: str | None, config_filename: str | None,
                        abs_config_path: str | None) -> Path:
    """Where the YAML is: ``abs_config_path``, ``<config_file_pkg>/config/<config_filename>``, or the default."""
    if abs_config_path:
        return Path(abs_config_path)
    default = f"{algo}_goal.yaml" if goal else f"{algo}.yaml"
    if config_file_pkg in (None, "", "uniros", "sb3_ros_support", "frobs_rl"):
        name = config_filename if config_file_pkg and config_filename else default
        shipped = resources.files("uniros.sb3").joinpath("config", name)
        if not shipped.is_file():
            raise TrainingConfigError(f"no config {name!r} shipped with uniros.sb3; pass abs_config_path")
        return Path(str(shipped))
    root = _package_dir(config_file_pkg, "config_file_pkg")
    name = config_filename or default
    candidates = [root / "config" / name, root / name]
    for path in candidates:
        if path.is_file():
            return path
    raise TrainingConfigError(f"config {name!r} not found in package {config_file_pkg!r}; looked at: "
                              + ", ".join(str(c) for c in candidates))


def _under(root: Path | None, path: str | Path) -> Path:
    if root is None:
        return Path(path)
    return root / str(path).strip("/")


class BasicModel:
    """A Stable-Baselines3 model built from a YAML, trained with checkpoints and logs.

    Args:
        env: the training env (a gymnasium env, possibly wrapped).
        save_model_path: folder for checkpoints and the trained model (relative to ``model_pkg_path``
            when given).
        log_path: folder for the logs (``log_path/<log_folder>/``).
        model_pkg_path: a package whose root the two paths are relative to.
        load_trained: load the trained model at ``load_model_path`` (or ``save_model_path``) for
            prediction, instead of creating one.
        config_file_pkg, config_filename, abs_config_path: where the YAML is (default: the one
            shipped for the algorithm).
        use_her: HER replay (goal classes; also when the YAML says ``use_HER: True``).
        seed: overrides the YAML's seed.
        eval_env: an env to evaluate on every ``eval_freq`` steps (``best_model.zip`` in
            ``save_model_path``); none by default.
        device: ``auto``, ``cpu``, ``cuda`` or ``cuda:N``; replaces the YAML's ``<algo>_params.device``
            (default ``auto``: the GPU for policies that see camera images when CUDA is present, else
            the CPU; :mod:`uniros.devices`). A loaded model loads onto it too.
    """

    algorithm = "sac"
    goal = False

    def __init__(self, env: Any, save_model_path: str | Path, log_path: str | Path, model_pkg_path: str | None = None,
                 load_trained: bool = False, load_model_path: str | Path | None = None,
                 config_file_pkg: str | None = None, config_filename: str | None = None,
                 abs_config_path: str | None = None, use_her: bool = False, seed: int | None = None,
                 eval_env: Any = None, ns: str = "/", verbose: int = 1, device: str | None = None,
                 **legacy: Any) -> None:
        for key in ("load_il_policy",):
            if legacy.pop(key, False):
                raise TrainingError("imitation-learning initialisation (load_il_policy) is not supported")
        legacy.pop("il_policy_path", None)
        legacy.pop("action_noise_type", None)
        if legacy:
            raise TypeError(f"{type(self).__name__} got unexpected keyword argument(s) {sorted(legacy)}")
        root = _package_dir(model_pkg_path, "model_pkg_path") if model_pkg_path else None
        self.env = env
        self.save_model_path = _under(root, save_model_path)
        self.log_path = _under(root, log_path)
        config_path = resolve_config_path(self.algorithm, self.goal, config_file_pkg, config_filename, abs_config_path)
        self.config: TrainingConfig = load_training_config(config_path, algorithm=self.algorithm)
        self.config_path = config_path
        if seed is not None:
            self.config.seed = seed
        if device is not None:
            self.config.algo_params["device"] = check_device(device, f"{type(self).__name__}(device=...)")
        self.config.use_her = bool(self.goal and (use_her or self.config.use_her))
        self.config.progress_bar = False
        self.config.n_envs = _n_envs_of(env, self.config)
        changed = fit_learning_starts(None, self.config, episode_steps=_episode_limit(env))
        if changed:
            _logger.warning("%s", changed)
        self.session = Session(self.config, env, make_eval_env=(lambda: eval_env) if eval_env is not None else None,
                               verbose=verbose, success_info=reports_success(env))
        if load_trained:
            target = _under(root, load_model_path) if load_model_path else self.save_model_path
            self.session.build(load=target)
        elif self.config.load_model:
            if not self.config.model_name:
                raise TrainingConfigError(f"{config_path}: load_model is true but model_name is not set")
            model_file = self.save_model_path / self.config.model_name
            self.session.build(load=model_file)
            buffer = self.save_model_path / f"{self.config.model_name}_replay_buffer.pkl"
            if buffer.is_file() and hasattr(self.session.model, "replay_buffer"):
                load_replay_buffer(self.session.model, buffer)
        else:
            self.session.build()
        self.model = self.session.model
        self.log_dir = self._log_dir()
        self.session.paths = Paths(checkpoints=self.save_model_path, prefix=self.config.save_prefix, logs=self.log_dir,
                                   evaluations=self.save_model_path / "evaluations.csv" if eval_env is not None
                                   else None, best_model=self.save_model_path / "best_model.zip" if eval_env
                                   is not None else None)
        self.set_model_logger()

    def _log_dir(self) -> Path:
        folder = self.config.log_folder or f"{self.algorithm.upper()}_1"
        path = self.log_path / folder
        n = 1
        while path.exists():
            n += 1
            path = self.log_path / f"{folder}_{n}"
        if n > 1:
            _logger.warning("log folder %s exists; logging to %s", self.log_path / folder, path)
        return path

    def set_model_logger(self) -> None:
        """Log to ``log_path/<log_folder>/`` (stdout, CSV and TensorBoard)."""
        from stable_baselines3.common.logger import configure

        self.model.set_logger(configure(str(self.log_dir), ["stdout", "csv", "tensorboard"]))

    def train(self, action_cycle_time: float | None = None) -> bool:
        """Train for ``training_steps`` (more) steps, with checkpoints every ``save_freq``; then save the model.

        Raises:
            TrainingInterrupted: Ctrl-C or SIGTERM (a ``KeyboardInterrupt``), after saving a checkpoint.
        """
        if action_cycle_time:
            _logger.warning("action_cycle_time is ignored: set the env's action_cycle_time instead")
        steps = self.config.training_steps
        if self.config.reset_num_timesteps:
            self.session.learn(steps, reset_num_timesteps=True)
        else:
            self.session.learn(int(self.model.num_timesteps) + steps)
        self.save_model()
        return True

    def save_model(self) -> Path:
        """Save ``<save_model_path><trained_model_name>.zip`` (a date suffix if the name is taken),
        its normalisation statistics, and the replay buffer when ``save_replay_buffer``."""
        name = self.config.trained_model_name
        path = self.save_model_path / f"{name}.zip"
        if path.exists():
            path = self.save_model_path / f"{name}_{time.strftime('%d_%m_%Y_%H_%M_%S')}.zip"
        save_model_with_stats(self.model, self.session.normalizer, path)
        if self.config.save_replay_buffer and getattr(self.model, "replay_buffer", None) is not None:
            save_replay_buffer(self.model, path.with_name(path.stem + "_replay_buffer.pkl"))
        self.saved_model = path
        return path

    def save_replay_buffer(self) -> None:
        """Save the replay buffer beside the last saved model."""
        path = getattr(self, "saved_model", self.save_model_path / f"{self.config.trained_model_name}.zip")
        save_replay_buffer(self.model, path.with_name(path.stem + "_replay_buffer.pkl"))

    def predict(self, observation: Any, state: Any = None, mask: Any = None, deterministic: bool = False) -> Any:
        """The model's action (observations normalised as in training when ``normalize`` is on)."""
        norm = self.session.normalizer
        obs = observation if norm is None else norm.normalize_obs(observation)
        return self.model.predict(obs, state=state, episode_start=mask, deterministic=deterministic)

    def check_env(self) -> None:
        """SB3's env checker on the training env."""
        from stable_baselines3.common.env_checker import check_env

        check_env(self.env)

    def close_env(self) -> None:
        """Close the env(s)."""
        self.session.close()

    @classmethod
    def load_trained_model(cls, model_path: str | Path, model_pkg: str | None = None, env: Any = None,
                           config_file_pkg: str | None = None, config_filename: str | None = None,
                           abs_config_path: str | None = None, device: str = "auto") -> Any:
        """Load a trained model for prediction (SB3's ``load``; the config is not needed), onto
        ``device`` (``auto``: the GPU for a policy that sees camera images when CUDA is present)."""
        from uniros.trainer import algorithm_class

        path = _under(_package_dir(model_pkg, "model_pkg") if model_pkg else None, model_path)
        if env is None:
            target = path if path.is_file() else path.with_name(path.name + ".zip")
            if not target.is_file():
                raise TrainingError(f"model file {str(path)!r} not found")
            from stable_baselines3.common.save_util import load_from_zip_file

            data, _, _ = load_from_zip_file(str(target), load_data=True, device="cpu")
            space = (data or {}).get("observation_space")
            return algorithm_class(cls.algorithm).load(str(target), device=resolve_device(device, space))
        from stable_baselines3.common.vec_env import DummyVecEnv

        return load_model(path, DummyVecEnv([lambda: env]), algorithm=cls.algorithm, device=device)

    load_trained = load_trained_model  # FRobs_RL's name


def _episode_limit(env: Any) -> int | None:
    """The episode step limit of a ``VecEnv``'s envs (a batch's, or the first env's spec), if known."""
    from stable_baselines3.common.vec_env import VecEnv

    batch = getattr(env, "batch", None)
    if batch is not None:
        return batch.max_episode_steps
    if hasattr(env, "max_episode_steps"):  # uniros.vec_env.WorkerVecEnv (the envs in worker processes)
        return env.max_episode_steps
    if isinstance(env, VecEnv):
        return getattr(env.get_attr("spec", [0])[0], "max_episode_steps", None)
    return None


def _n_envs_of(env: Any, config: TrainingConfig) -> int:
    """How many envs ``env`` steps at once: the env given decides, and the YAML's ``n_envs`` must agree.

    A trainer class trains the env it is given; a YAML ``n_envs`` of 1 (the default) takes any env.
    """
    from stable_baselines3.common.vec_env import VecEnv

    n = env.num_envs if isinstance(env, VecEnv) else 1
    if config.n_envs not in (1, n):
        raise TrainingConfigError(
            f"{config.source}: n_envs is {config.n_envs} but the env given steps {n}; a trainer class trains the "
            f"env it is given: pass uniros.vec_env.make_batched_vec_env(ID, {config.n_envs}), or drop n_envs"
        )
    return n


__all__ = ["BasicModel", "normalizer_path", "resolve_config_path"]
