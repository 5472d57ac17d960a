"""The one training implementation under ``uniros train``, :func:`uniros.training.train` and the
sb3_ros_support-style classes (:mod:`uniros.sb3`).

A :class:`Session` wraps the env (Monitor, VecNormalize), builds or loads the SB3 model, and runs
``model.learn`` with SB3 callbacks: :class:`CheckpointEvery` (SB3's ``CheckpointCallback``, writing
atomically, with the replay buffer and normalisation statistics) and :class:`SuccessEval` (SB3's
``EvalCallback``, recording the success rate and keeping the best model). Ctrl-C and SIGTERM during
``learn`` save a checkpoint and raise :class:`TrainingInterrupted`.
"""

from __future__ import annotations

import contextlib
import logging
import math
import signal
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from uniros.algorithms import (
    algorithm_class,
    is_off_policy,
    policy_names,
    takes_action_noise,
)
from uniros.checkpoints import (
    Checkpoint,
    latest_checkpoint,
    normalizer_path,
    own_folder,
    put_replay_buffer,
    read_replay_buffer,
    replay_buffer_problem,
    save_checkpoint,
    save_model_with_stats,
)
from uniros.devices import resolve_device
from uniros.errors import TrainingError
from uniros.evaluation import EVAL_SEED, evaluate
from uniros.image_spaces import images_channel_first, vector_keys
from uniros.interrupts import StopRequest, TrainingInterrupted, signals_deferred, stop_at_next_step
from uniros.model_files import ModelFileError, algorithm_of, init_parameters, load_model, spaces_mismatch
from uniros.train_config import TrainingConfig, TrainingConfigError

_logger = logging.getLogger(__name__)


# -- building ------------------------------------------------------------------------------------
def apply_torch_threads(threads: int) -> int:
    """Set torch's CPU threads for training and return the number set.

    ``threads >= 1``: that many, capped at the CPU count (one is fastest for the small MLPs of these
    tasks: ~1.8x faster than two on a 2-core machine, where the learner bounds the wall clock);
    ``0``: torch's own default (all cores).
    """
    import os

    import torch

    cores = os.cpu_count() or 1
    n = cores if threads <= 0 else min(int(threads), cores)
    if torch.get_num_threads() != n:
        torch.set_num_threads(n)
    return n


def _activation(name: str) -> Any:
    import torch.nn as nn

    table = {"relu": nn.ReLU, "tanh": nn.Tanh, "elu": nn.ELU, "selu": nn.SELU, "leaky_relu": nn.LeakyReLU}
    try:
        return table[str(name).lower()]
    except KeyError:
        raise TrainingConfigError(f"activation_fn {name!r} is not one of {sorted(table)}") from None


def _policy_kwargs(config: TrainingConfig) -> dict[str, Any] | None:
    if not config.policy_params:
        return None
    import torch.optim as optim
    from stable_baselines3.common import torch_layers

    pk = dict(config.policy_params)
    if "activation_fn" in pk:
        pk["activation_fn"] = _activation(pk["activation_fn"])
    if isinstance(pk.get("optimizer_class"), str):
        name = pk["optimizer_class"]
        if not hasattr(optim, name):
            raise TrainingConfigError(f"{config.source}: optimizer_class {name!r} is not a torch.optim optimizer")
        pk["optimizer_class"] = getattr(optim, name)
    if isinstance(pk.get("features_extractor_class"), str):
        # FRobs_RL names FlattenExtractor for Box observations; dict observations need CombinedExtractor.
        name = pk.pop("features_extractor_class")
        if not hasattr(torch_layers, name):
            raise TrainingConfigError(f"{config.source}: features_extractor_class {name!r} is not an SB3 extractor")
        if name not in ("FlattenExtractor", "CombinedExtractor", "BaseFeaturesExtractor"):
            pk["features_extractor_class"] = getattr(torch_layers, name)
    return pk


def build_model(config: TrainingConfig, env: Any, *, verbose: int = 0) -> Any:
    """The model for ``config`` on ``env`` (a gymnasium env or a VecEnv), of the class
    :data:`uniros.algorithms.ALGOS` names, on the device ``<algo>_params.device`` resolves to
    (:func:`uniros.devices.resolve_device`: ``auto`` puts image policies on a present GPU)."""
    from gymnasium import spaces
    from stable_baselines3 import HerReplayBuffer
    from stable_baselines3.common.noise import NormalActionNoise, OrnsteinUhlenbeckActionNoise

    apply_torch_threads(config.torch_threads)
    cls = algorithm_class(config.algorithm)
    kwargs: dict[str, Any] = dict(config.algo_params)
    kwargs.setdefault("seed", config.seed)
    obs_space = env.observation_space
    kwargs["device"] = resolve_device(kwargs.get("device"), obs_space,
                                      f"{config.source}: {config.algorithm}_params.device")
    policy = "MultiInputPolicy" if isinstance(obs_space, spaces.Dict) else "MlpPolicy"
    if policy not in policy_names(config.algorithm):
        raise TrainingConfigError(f"{config.source}: {config.algorithm} has no {policy} (it has "
                                  f"{list(policy_names(config.algorithm))}): pick another algorithm for this env's "
                                  f"{type(obs_space).__name__} observations")
    if config.use_her:
        if not isinstance(obs_space, spaces.Dict):
            raise TrainingConfigError(f"{config.source}: use_HER needs a goal env (Dict observation space)")
        kwargs["replay_buffer_class"] = HerReplayBuffer
        kwargs["replay_buffer_kwargs"] = {"n_sampled_goal": 4, "goal_selection_strategy": "future", **config.her_params}
    pk = _policy_kwargs(config)
    if pk is not None:
        kwargs["policy_kwargs"] = pk
    if config.use_sde:
        kwargs["use_sde"] = True
        kwargs.update(config.sde_params)
    if config.action_noise is not None and takes_action_noise(config.algorithm):
        if not isinstance(env.action_space, spaces.Box):
            raise TrainingConfigError(f"{config.source}: use_action_noise needs a continuous (Box) action space")
        n = env.action_space.shape[0]
        mean = np.full(n, float(config.action_noise.get("mean", 0.0)))
        sigma = np.full(n, float(config.action_noise.get("sigma", 0.1)))
        if config.action_noise_type == "ornstein":
            extra = {k: float(config.action_noise[k]) for k in ("theta", "dt") if k in config.action_noise}
            kwargs["action_noise"] = OrnsteinUhlenbeckActionNoise(mean=mean, sigma=sigma, **extra)
        else:
            kwargs["action_noise"] = NormalActionNoise(mean=mean, sigma=sigma)
    from uniros.resources import check_replay_buffer_memory

    check_replay_buffer_memory(config, cls, kwargs, obs_space, env.action_space, her=config.use_her)
    try:
        return cls(policy, env, verbose=verbose, **kwargs)
    except (TypeError, AssertionError, ValueError) as exc:
        raise TrainingConfigError(f"{config.source}: {config.algorithm}_params: {exc}") from exc
    except MemoryError as exc:  # NumPy's "Unable to allocate ..." for the replay buffer
        raise TrainingConfigError(f"{config.source}: the model does not fit in memory ({exc}): lower "
                                  f"{config.algorithm}_params.buffer_size or the camera image size") from None


# -- callbacks -----------------------------------------------------------------------------------
def _aligned(cls: type) -> type:
    """Count calls from the model's step count, so a resumed run keeps the schedule (every N steps)."""

    class Aligned(cls):  # type: ignore[misc, valid-type]
        def _on_training_start(self) -> None:
            super()._on_training_start()
            self.n_calls = int(self.model.num_timesteps) // max(1, self.model.n_envs)

    Aligned.__name__ = cls.__name__
    return Aligned


def _per_vector_step(env_steps: int, n_envs: int) -> int:
    """A schedule in env steps as SB3's callbacks count it, in vector steps (calls): at least 1, and
    0 (off) for 0."""
    return 0 if env_steps <= 0 else max(1, env_steps // max(1, n_envs))


def _callback_classes() -> tuple[type, type, type]:
    from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback

    class StopOnRequest(BaseCallback):  # type: ignore[misc]
        """Ends ``learn`` at the first env step after a stop was requested (see ``stop_at_next_step``)."""

        def __init__(self, request: StopRequest) -> None:
            super().__init__()
            self.request = request

        def _on_step(self) -> bool:
            return self.request.signum is None

    class CheckpointEvery(_aligned(CheckpointCallback)):  # type: ignore[misc]
        """SB3's ``CheckpointCallback``, saving through the session (atomic files, ``latest.json``,
        retention)."""

        def __init__(self, session: Session, save_freq: int) -> None:
            super().__init__(save_freq=_per_vector_step(save_freq, session.model.n_envs),
                             save_path=str(session.paths.checkpoints),
                             name_prefix=session.paths.prefix, save_replay_buffer=True, save_vecnormalize=True)
            self.session = session

        def _on_step(self) -> bool:
            if self.n_calls % self.save_freq == 0:
                self.session.checkpoint()
            return True

    class SuccessEval(_aligned(BaseCallback)):  # type: ignore[misc]
        """SB3's ``EvalCallback`` on uniros' seeded evaluation episodes: every ``eval_freq`` env
        steps, ``eval_episodes`` deterministic episodes (episode i reset with ``EVAL_SEED + i``,
        observations normalised with the training statistics), the success rate recorded
        (``eval/success_rate`` in TensorBoard) and the best model kept."""

        def __init__(self, session: Session, eval_env: Any) -> None:
            super().__init__()
            self.session, self.eval_env = session, eval_env
            self.eval_freq = _per_vector_step(session.config.eval_freq, session.model.n_envs)

        def _on_step(self) -> bool:
            if not (self.eval_freq > 0 and self.n_calls % self.eval_freq == 0):
                return True
            s = self.session
            if s.stop_request.signum is not None:
                return False
            started, seconds = time.perf_counter(), s.train_seconds()  # before this evaluation
            stats = evaluate(self.model, self.eval_env, s.config.eval_episodes, seed=EVAL_SEED,
                             normalizer=s.normalizer)
            rate = stats["success_rate"] if s.success_info else float("nan")
            self.logger.record("eval/mean_reward", stats["mean_return"])
            self.logger.record("eval/mean_ep_length", stats["mean_length"])
            if s.success_info:
                self.logger.record("eval/success_rate", rate)
            self.logger.dump(self.num_timesteps)
            keep_going = s.after_eval(int(self.num_timesteps), rate, stats["mean_return"], seconds=seconds,
                                      episodes=int(stats["episodes"]), std_return=stats["std_return"],
                                      mean_length=stats["mean_length"])
            s.excluded += time.perf_counter() - started
            return keep_going

    return StopOnRequest, CheckpointEvery, SuccessEval


# -- the session ---------------------------------------------------------------------------------
@dataclass
class Paths:
    """Where a session writes (``None``: not written)."""

    checkpoints: Path | None = None
    prefix: str = "model"
    logs: Path | None = None
    monitor: Path | None = None
    evaluations: Path | None = None
    best_model: Path | None = None
    meta: Path | None = None


@dataclass
class Session:
    """One training run: env wrapping, model, callbacks, interruption.

    Args:
        config: the training config.
        env: the training env: a gymnasium env, or an SB3 ``VecEnv`` of ``config.n_envs`` envs.
        make_eval_env: builds the evaluation env (``None``: no evaluation).
        paths: output locations.
        on_eval: ``callback(steps, train_seconds, success_rate)`` after each evaluation.
        target: success rate that counts as solved (``steps_to_success``).
    """

    config: TrainingConfig
    env: Any
    make_eval_env: Callable[[], Any] | None = None
    paths: Paths = field(default_factory=Paths)
    on_eval: Callable[[int, float, float], None] | None = None
    target: float = 0.9
    verbose: int = 0
    success_info: bool = True
    model: Any = None
    normalizer: Any = None
    evaluations: list[dict[str, float]] = field(default_factory=list)
    steps_to_success: int | None = None
    seconds_to_success: float | None = None
    prior_seconds: float = 0.0
    excluded: float = 0.0
    stop_request: StopRequest = field(default_factory=StopRequest)
    _eval_env: Any = None
    _learn_started: float = 0.0

    # -- environments --
    def _monitored(self, env: Any, name: str) -> Any:
        """The training env as an SB3 ``VecEnv`` whose episodes go to ``<monitor>/<name>.monitor.csv``.

        A gymnasium env gets SB3's ``Monitor`` in a ``DummyVecEnv``; a ``VecEnv`` (``n_envs`` > 1:
        the batched vector env) gets ``VecMonitor``, which writes the same file.
        """
        from stable_baselines3.common.monitor import Monitor
        from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, VecMonitor

        filename = None if self.paths.monitor is None else str(self.paths.monitor / name)
        keys = ("is_success",) if self.success_info else ()
        # A new file gets SB3's header lines (SB3 writes them only when overriding); a resumed run appends.
        fresh = filename is None or not Path(f"{filename}.{Monitor.EXT}").is_file()
        if isinstance(env, VecEnv):
            from stable_baselines3.common.monitor import ResultsWriter

            monitored = VecMonitor(env, info_keywords=keys)
            if filename is not None:  # VecMonitor would always start a new file: a resumed run appends
                monitored.results_writer = ResultsWriter(filename, header={"t_start": monitored.t_start},
                                                         extra_keys=keys, override_existing=fresh)
            return monitored
        monitored = Monitor(env, filename=filename, info_keywords=keys, override_existing=fresh)
        return DummyVecEnv([lambda: monitored])

    def _eval_monitored(self, env: Any) -> Any:
        """The evaluation env (one gymnasium env), its episodes in ``<monitor>/eval.monitor.csv``."""
        from stable_baselines3.common.monitor import Monitor

        filename = None if self.paths.monitor is None else str(self.paths.monitor / "eval")
        fresh = filename is None or not Path(f"{filename}.{Monitor.EXT}").is_file()
        return Monitor(env, filename=filename, info_keywords=("is_success",) if self.success_info else (),
                       override_existing=fresh)

    def _vec(self, venv: Any, *, training: bool, stats: Path | None = None) -> Any:
        """The training env as the model sees it: camera images channel-first (below the normaliser,
        so that HER's buffer holds them as the model's space says), then the normaliser, which
        leaves images out."""
        from stable_baselines3.common.vec_env import VecNormalize

        venv = images_channel_first(venv)
        if not self.config.normalize:
            return venv
        gamma = float(self.config.algo_params.get("gamma", 0.99))
        if stats is not None:
            norm = VecNormalize.load(str(stats), venv)
            norm.training = training
        else:
            norm = VecNormalize(venv, gamma=gamma, norm_reward=False, training=training,
                                norm_obs_keys=vector_keys(venv.observation_space))
        return norm

    def _logger(self) -> None:
        from stable_baselines3.common.logger import configure

        if self.paths.logs is not None:
            formats = ["csv", "tensorboard"] + (["stdout"] if self.verbose else [])
            self.model.set_logger(configure(str(self.paths.logs), formats))

    # -- model --
    def build(self, resume: Checkpoint | None = None, load: Path | None = None, *, buffer: Any = None,
              load_kwargs: dict[str, Any] | None = None, init: Path | None = None,
              init_buffer: Path | None = None) -> Any:
        """Create the model, or load it from a checkpoint (``resume``) or a saved model (``load``).

        Args:
            buffer: the checkpoint's replay buffer, already read
                (:func:`uniros.checkpoints.check_checkpoint`); with ``resume`` and no buffer, an
                off-policy model starts from an empty one that fills for ``learning_starts`` steps
                (and the demonstrations) before updates go on.
            load_kwargs: hyperparameters that replace the saved model's (SB3's ``load(**kwargs)``).
            init: a saved model a new model starts from (a warm start,
                :func:`uniros.model_files.init_parameters`): the config's hyperparameters, an empty
                replay buffer (and the demonstrations), step 0, the saved model's weights and statistics.
            init_buffer: with ``init``, a replay buffer file the new model starts with instead of an
                empty one (the run it starts from: its transitions stay beside the new worlds' ones).

        Raises:
            TrainingError: ``init_buffer`` is unreadable or does not fit the env or config.
        """
        from stable_baselines3.common.vec_env import VecEnv

        apply_torch_threads(self.config.torch_threads)
        if not isinstance(self.env, VecEnv):
            self.env.reset(seed=self.config.seed)
        elif self.config.seed is not None:
            self.env.seed(self.config.seed)  # env i's first reset gets seed + i (SB3's convention)
        source = resume.model if resume is not None else load
        if source is not None and init is not None:
            raise ValueError("a model is either loaded or started from another one (init), not both")
        stats = resume.vecnormalize if resume is not None else None
        weights = source if source is not None else init
        if weights is not None and stats is None and self.config.normalize:
            candidate = normalizer_path(Path(weights))
            stats = candidate if candidate.is_file() else None
        venv = self._vec(self._monitored(self.env, "train"), training=True, stats=stats)
        self.normalizer = venv if self.config.normalize else None
        if source is None:
            self.model = build_model(self.config, venv, verbose=self.verbose)
            if init is not None:
                init_parameters(self.model, Path(init), self.config.algorithm)
            if init_buffer is not None:
                self._put_init_buffer(Path(init_buffer))
            self._add_demonstrations()
        else:
            self.model = load_model(Path(source), venv, algorithm=self.config.algorithm, device=self.config.device,
                                    **(load_kwargs or {}))
            if buffer is not None:
                put_replay_buffer(self.model, buffer)
            elif resume is not None and is_off_policy(self.config.algorithm):
                self._refill_from(int(self.model.num_timesteps))
        self._logger()
        if self.make_eval_env is not None and self.config.eval_freq > 0:
            self._eval_env = self._eval_monitored(self.make_eval_env())
        return self.model

    def _put_init_buffer(self, path: Path) -> None:
        if getattr(self.model, "replay_buffer", None) is None:
            raise TrainingError(f"{path}: a replay buffer, but {self.config.algorithm.upper()} has none (off-policy "
                                "algorithms only)")
        try:
            buffer = read_replay_buffer(path)
        except ValueError as exc:
            raise TrainingError(f"{path}: {exc}") from None
        problem = replay_buffer_problem(buffer, self.model)
        if problem:
            raise TrainingError(f"{path}: does not fit this run: {problem}")
        put_replay_buffer(self.model, buffer)
        _logger.info("started with the replay buffer %s (%d transitions)", path, buffer.size() * buffer.n_envs)

    def _add_demonstrations(self) -> None:
        """Put ``config.demonstrations`` scripted episodes (seeds ``seed + 10,000 + k``) and the episodes of the
        recorded dataset ``config.demos`` (:mod:`uniros.demonstrations_io`) into the replay buffer."""
        if not self.config.demonstrations and not self.config.demos:
            return
        if self.make_eval_env is None or self.model.n_envs != 1:
            raise TrainingConfigError(f"{self.config.source}: demonstrations need n_envs: 1 and an env to play them in")
        if self.config.demonstrations:
            from rl_environments.manipulation_scripted import fill_replay_buffer

            env = self.make_eval_env()
            try:
                stats = fill_replay_buffer(self.model, env, self.config.demonstrations,
                                           seed=(self.config.seed or 0) + 10_000)
            except (AttributeError, ValueError) as exc:
                raise TrainingConfigError(f"{self.config.source}: demonstrations: no scripted policy for this env "
                                          f"({exc}); uniros has them for push and pick-and-place") from exc
            finally:
                env.close()
            _logger.info("%d demonstration episodes (%d transitions, success %.2f) in the replay buffer",
                         stats["episodes"], stats["transitions"], stats["success_rate"])
        if self.config.demos:
            from uniros.demonstrations_io import DemonstrationsError, fill_replay_buffer_from_dataset

            env = self.make_eval_env()
            try:
                stats = fill_replay_buffer_from_dataset(self.model, self.config.demos, env)
            except DemonstrationsError as exc:
                raise TrainingConfigError(f"demos: {exc}") from None
            finally:
                env.close()
            _logger.info("%d recorded episodes (%d transitions, success %.2f) from %s in the replay buffer",
                         stats["episodes"], stats["transitions"], stats["success_rate"], self.config.demos)

    def _refill_from(self, steps: int) -> None:
        """An off-policy model resumed without its replay buffer: updates wait until the empty buffer
        holds ``learning_starts`` new steps (at least an episode per env, which HER needs)."""
        starts = int(self.config.algo_params.get("learning_starts", 100))
        limit = getattr(getattr(self.make_eval_env, "spec", None), "max_episode_steps", None)
        self.model.learning_starts = steps + max(starts, int(limit or 0) * int(self.model.n_envs))
        self._add_demonstrations()

    def restore_success(self, rows: list[dict[str, float]]) -> None:
        """Set ``steps_to_success``/``seconds_to_success`` from earlier evaluations (a resumed run)."""
        hit = next((r for r in rows if r.get("success_rate", float("nan")) >= self.target), None)
        self.steps_to_success = None if hit is None else int(hit["steps"])
        self.seconds_to_success = None if hit is None else float(hit.get("train_seconds", float("nan")))

    # -- outputs --
    def checkpoint(self) -> Checkpoint | None:
        """Save a checkpoint now (model, replay buffer, normalisation); ``None`` without a folder."""
        if self.paths.checkpoints is None or self.model is None:
            return None
        if self.paths.meta is not None:  # a run folder: saved and pruned in the run's own checkpoints/ only
            own_folder(self.paths.checkpoints)
        started = time.perf_counter()
        ckpt = save_checkpoint(self.model, self.normalizer, self.paths.checkpoints, self.paths.prefix,
                               keep_checkpoints=self.config.keep_checkpoints,
                               keep_replay_buffers=self.config.keep_replay_buffers)
        self._write_meta(status="running")
        self.excluded += time.perf_counter() - started
        return ckpt

    def train_seconds(self) -> float:
        """Training wall-clock so far (evaluation and checkpoint saving excluded)."""
        if not self._learn_started:
            return self.prior_seconds
        return self.prior_seconds + time.perf_counter() - self._learn_started - self.excluded

    def _write_meta(self, **values: Any) -> None:
        if self.paths.meta is None:
            return
        from uniros.run_dir import RunDir

        RunDir(self.paths.meta.parent).update_meta(steps=int(self.model.num_timesteps),
                                                   train_seconds=round(self.train_seconds(), 3), **values)

    def after_eval(self, steps: int, rate: float, mean_return: float, *, seconds: float | None = None,
                   episodes: int | None = None, std_return: float | None = None,
                   mean_length: float | None = None) -> bool:
        """Record an evaluation, keep the best model; False stops training (``stop_at_success``).

        ``seconds``: training seconds at ``steps`` (default: now; the evaluation callback passes the
        time before it evaluated, which is not training). ``std_return`` and ``mean_length``: the
        evaluation's, written to ``evaluations.csv`` when given.
        """
        seconds = self.train_seconds() if seconds is None else seconds
        best = max(self.evaluations, key=_eval_key, default=None)
        row = {"steps": steps, "train_seconds": round(seconds, 3), "success_rate": rate, "mean_return": mean_return,
               "episodes": self.config.eval_episodes if episodes is None else episodes}
        for key, value in (("std_return", std_return), ("mean_length", mean_length)):
            if value is not None and math.isfinite(value):
                row[key] = value
        self.evaluations.append(row)
        if self.paths.evaluations is not None:
            from uniros.reports import write_evaluations

            write_evaluations(self.paths.evaluations, self.evaluations)
        if self.paths.best_model is not None and (best is None or _eval_key(row) > _eval_key(best)):
            save_model_with_stats(self.model, self.normalizer, self.paths.best_model)
        if self.on_eval is not None:
            self.on_eval(steps, seconds, rate)
        if rate >= self.target and self.steps_to_success is None:
            self.steps_to_success, self.seconds_to_success = steps, seconds
        stop = self.config.stop_at_success
        return not (stop is not None and rate >= stop)

    # -- learning --
    def learn(self, total_steps: int | None = None, *, reset_num_timesteps: bool = False,
              progress_bar: bool | None = None) -> None:
        """Train until the model has ``total_steps`` (default: ``training_steps``) env steps.

        Raises:
            TrainingInterrupted: on Ctrl-C or SIGTERM, after saving a checkpoint.
        """
        stop_cls, checkpoint_cls, eval_cls = _callback_classes()
        total = self.config.training_steps if total_steps is None else total_steps
        remaining = total if reset_num_timesteps else total - int(self.model.num_timesteps)
        if remaining <= 0:
            return
        bar = self.config.progress_bar if progress_bar is None else progress_bar
        self._learn_started, self.excluded = time.perf_counter(), 0.0
        try:
            with stop_at_next_step() as self.stop_request:
                callbacks: list[Any] = [stop_cls(self.stop_request)]
                if self.paths.checkpoints is not None and self.config.save_freq > 0:
                    callbacks.append(checkpoint_cls(self, self.config.save_freq))
                if self._eval_env is not None:
                    callbacks.append(eval_cls(self, self._eval_env))
                self.model.learn(total_timesteps=remaining, callback=callbacks, log_interval=self.config.log_interval,
                                 reset_num_timesteps=reset_num_timesteps, progress_bar=bar)
        except KeyboardInterrupt as exc:
            # A second signal, or Ctrl-C outside the main thread's handler: the model may be mid update,
            # so no checkpoint is written now; the last complete one stands.
            self._stop_interrupted(getattr(exc, "signum", signal.SIGINT), save=False)
        if self.stop_request.signum is not None:
            self._stop_interrupted(self.stop_request.signum, save=True)
        self.prior_seconds, self._learn_started, self.excluded = self.train_seconds(), 0.0, 0.0

    def _stop_interrupted(self, signum: int, *, save: bool) -> None:
        """Record the interruption (with a new checkpoint when ``save``) and raise ``TrainingInterrupted``."""
        with signals_deferred():
            ckpt = self.checkpoint() if save else None
            self._write_meta(status="interrupted")
        if not save and self.paths.checkpoints is not None:
            found = latest_checkpoint(self.paths.checkpoints)
            ckpt = found[0] if found else None
        name = signal.Signals(signum).name
        if ckpt is not None:
            where = f"; checkpoint at {ckpt.steps} steps: {ckpt.model}"
        else:
            where = " (no checkpoint folder)" if self.paths.checkpoints is None else " before the first checkpoint"
        raise TrainingInterrupted(f"training interrupted by {name}{where}", signum, ckpt) from None

    def close(self) -> None:
        """Close the training and evaluation envs."""
        for env in (self.env, self._eval_env):
            if env is not None:
                with contextlib.suppress(Exception):
                    env.close()


def _eval_key(row: dict[str, float]) -> tuple[float, float]:
    rate = row["success_rate"]
    return (-1.0 if rate != rate else rate, row["mean_return"])


__all__ = [
    "Checkpoint",
    "ModelFileError",
    "Paths",
    "Session",
    "algorithm_class",
    "algorithm_of",
    "apply_torch_threads",
    "build_model",
    "latest_checkpoint",
    "load_model",
    "spaces_mismatch",
]
