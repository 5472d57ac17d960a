"""Training and evaluating Stable-Baselines3 agents on uniros envs from one YAML file.

One implementation (:mod:`uniros.trainer`) serves ``uniros train``, :func:`train` and the
sb3_ros_support-style classes of :mod:`uniros.sb3`. The YAML is sb3_ros_support's or FRobs_RL's
format (:mod:`uniros.train_config`); a run writes a run directory (:mod:`uniros.run_dir`) with
TensorBoard logs, monitor CSVs, checkpoints, the best and final models, a learning-curve plot and
a video; Ctrl-C or SIGTERM saves a checkpoint that :func:`run_training` resumes.

Configs shipped with uniros sit in ``config/training/`` (installed as
``rl_environments.config.training``), one per env ID; see :func:`default_config_for`.
"""

from __future__ import annotations

import copy
import importlib
import json
import logging
import os
import re
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from multiros.envs.real.core import SIMULATION_KNOBS, RealEnvCore
from rl_environments import SIM_TO_REAL
from rl_environments.arm_registry import ARM_TASKS
from uniros.checkpoints import normalizer_path, remove_stale_temporaries, save_model_with_stats
from uniros.evaluation import EVAL_SEED, evaluate, format_success, wilson_interval
from uniros.interrupts import TrainingInterrupted, sigterm_as_interrupt
from uniros.resources import check_disk_for_run, disk_full_error, run_state_after_disk_full
from uniros.run_dir import RunDir, RunDirError, check_run_name
from uniros.train_config import (
    ALGORITHMS,
    TrainingConfig,
    TrainingConfigError,
    TrainingError,
    default_config_for,
    load_training_config,
    parse_training_config,
    save_training_config,
)
from uniros.trainer import (
    ModelFileError,
    Paths,
    Session,
    build_model,
    load_model,
)

_logger = logging.getLogger(__name__)


# -- envs ------------------------------------------------------------------------------------------
def resolve_env_id(env_id: str) -> str:
    """Import the module of a ``module:ID`` env ID (gymnasium's form) and return the bare ID.

    Raises:
        TrainingError: the module cannot be imported, or does not register the ID.
    """
    import gymnasium as gym

    module, sep, bare = env_id.rpartition(":")
    if not sep:
        return env_id
    if module not in sys.modules:
        try:
            _import_env_module(module)
        except ImportError as exc:
            raise TrainingError(
                f"cannot import {module!r} (from env ID {env_id!r}): {exc}. Install the package, or run from "
                "the directory that contains it"
            ) from exc
    if bare not in gym.registry:
        import difflib

        close = difflib.get_close_matches(bare, list(gym.registry), n=3)
        raise TrainingError(f"{module!r} was imported but did not register {bare!r}"
                            + (f"; close: {close}" if close else ""))
    return bare


def _import_env_module(module: str) -> None:
    """Import ``module``; if it is not found and the working directory holds it, from there.

    ``python -m`` puts the working directory on ``sys.path``, but an installed console script
    (``uniros``) puts its own ``bin`` directory there, so a user's ``my_pkg`` next to them would not
    import. The working directory is added (as uvicorn's ``--app-dir`` does by default) only when
    the top-level package or module is found in it.
    """
    try:
        importlib.import_module(module)
        return
    except ModuleNotFoundError as exc:
        top = module.split(".")[0]
        cwd = os.getcwd()
        local = os.path.isdir(os.path.join(cwd, top)) or os.path.isfile(os.path.join(cwd, top + ".py"))
        if exc.name != top or not local or cwd in sys.path or "" in sys.path:
            raise
    sys.path.insert(0, cwd)
    importlib.invalidate_caches()
    importlib.import_module(module)


def make_env(env_id: str, **kwargs: Any) -> Any:
    """``uniros.make`` for a registered ID or a ``module:ID``.

    Raises:
        TrainingError: the env does not take one of ``kwargs`` (the message names it), or the simulation
            refused to make its world (a scene that does not fit the robot: one line naming the arm file).
    """
    import re

    import uniros
    from multiros.sim.client import SimulationServiceError
    from uniros.factory import EnvKeywordError, did_you_mean

    try:
        return uniros.make(resolve_env_id(env_id), **kwargs)
    except SimulationServiceError as exc:
        raise TrainingError(f"{env_id} cannot be made: {str(exc).splitlines()[0]}{_arm_hint(env_id)}") from None
    except TypeError as exc:
        match = re.search(r"unexpected keyword argument\(?s?\)? \[?'([^']+)'", str(exc))
        if match is None or match[1] not in kwargs:
            raise
        accepted = str(exc).partition(" accepts: ")[2]
        hint = did_you_mean({match[1]: exc.suggestions[match[1]]}) if isinstance(exc, EnvKeywordError) \
            and match[1] in exc.suggestions else ""
        raise TrainingError(f"{env_id} does not take the env kwarg {match[1]!r}{hint} (env_kwargs of the config, e.g. "
                            "a shipped RX200 config's ee_action_type on another env): remove it"
                            + (f"; it accepts: {accepted}" if accepted else "")) from None


def _arm_hint(env_id: str) -> str:
    """For an arm file's ID: which file, and the command that tries it."""
    path = arm_file_of(env_id)
    return "" if path is None else f" (its arm file {path}: `uniros arm check {path}` tries its tasks)"


_make_env = make_env  # ``train`` has a parameter of that name


def make_train_env(env_id: str, config: TrainingConfig, factory: Callable[[], Any] | None = None) -> Any:
    """The env ``config`` trains on: one env, or with ``n_envs`` > 1 a batched vector env.

    ``n_envs`` envs ``env_id`` share one simulation node and one request per step
    (:func:`uniros.vec_env.make_batched_vec_env`, ``env_kwargs`` to each env). With ``factory`` (a
    baseline's own env builder) they are ``factory``'s envs in SB3's ``DummyVecEnv`` instead.

    Raises:
        TrainingConfigError: ``n_envs`` > 1 for an env that cannot be batched (a real robot's).
    """
    n = config.n_envs
    if n == 1:
        return factory() if factory is not None else make_env(env_id, **config.env_kwargs)
    if factory is not None:
        from stable_baselines3.common.vec_env import DummyVecEnv

        return DummyVecEnv([factory] * n)
    from uniros.vec_env import make_batched_vec_env

    check_n_envs(env_id, config)
    return make_batched_vec_env(resolve_env_id(env_id), n, pin_workers=config.pin_workers, **config.env_kwargs)


def check_n_envs(env_id: str, config: TrainingConfig, origin: str | None = None) -> None:
    """Refuse an ``n_envs`` above 1 that cannot work, before anything is built or written.

    ``origin`` says where ``n_envs`` came from in the message (default: the config file).

    Raises:
        TrainingConfigError: the env cannot share a simulation node (a real robot's, or not a uniros
            env), or ``train_freq`` counts episodes (SB3 trains episodically with one env only).
    """
    import gymnasium as gym

    from multiros.envs.batch import batchable, env_creator

    n = config.n_envs
    if n == 1:
        return
    where = origin or f"{config.source}: n_envs: {n}"
    resolved = resolve_env_id(env_id)
    creator = env_creator(resolved) if resolved in gym.registry else None
    if creator is not None and not batchable(creator):
        kind = "drives a real robot" if issubclass(creator, RealEnvCore) else "is not a uniros simulated env"
        raise TrainingConfigError(f"{where} trains {n} envs of {env_id} in one simulation node, but {env_id} {kind}; "
                                  "train it with n_envs: 1")
    train_freq = config.algo_params.get("train_freq")
    if isinstance(train_freq, (tuple, list)) and len(train_freq) == 2 and str(train_freq[1]) == "episode":
        raise TrainingConfigError(f"{where}: train_freq counts episodes ({train_freq[0]}, episode), which SB3 does "
                                  "with one env only; count steps (train_freq: {freq: 1, unit: step}) or use n_envs: 1")


def fit_learning_starts(env_id: str | None, config: TrainingConfig, *, episode_steps: int | None = None) -> str | None:
    """Raise HER's ``learning_starts`` to ``n_envs`` episodes, so learning starts after an ended one.

    SB3's ``HerReplayBuffer`` samples only from ended episodes and raises before the first. One env
    ends its first episode (at the latest) after ``max_episode_steps`` steps; ``n_envs`` envs step
    together, so that takes ``n_envs * max_episode_steps`` env steps. The episode limit is
    ``episode_steps``, else the config's ``env_kwargs`` or ``env_id``'s registration. Returns what
    was changed, or ``None``.
    """
    import gymnasium as gym

    if not config.use_her or config.n_envs == 1:
        return None
    limit = episode_steps or config.env_kwargs.get("max_episode_steps")
    if limit is None and env_id is not None:
        resolved = resolve_env_id(env_id)
        limit = gym.spec(resolved).max_episode_steps if resolved in gym.registry else None
    starts = int(config.algo_params.get("learning_starts", 100))
    if limit is None or starts >= config.n_envs * int(limit):
        return None
    config.algo_params["learning_starts"] = config.n_envs * int(limit)
    return (f"learning_starts {starts} -> {config.n_envs * int(limit)}: HER samples only ended episodes, and "
            f"{config.n_envs} envs of {limit}-step episodes end their first after {config.n_envs} x {limit} steps")


def reports_success(env: Any, env_id: str | None = None) -> bool:
    """Whether ``env`` (or the sub-envs of an SB3 ``VecEnv``) puts ``is_success`` in its infos.

    ``env_id`` names the registered ID when the env has no ``spec`` (a batched vector env's envs).
    Sub-envs in other processes (``SubprocVecEnv``) are judged by their spec and their spaces.
    """
    import gymnasium as gym
    from gymnasium_robotics.core import GoalEnv
    from stable_baselines3.common.vec_env import VecEnv

    import rl_environments

    if isinstance(env, VecEnv) and not hasattr(env, "envs"):
        space = env.observation_space
        goal = isinstance(space, gym.spaces.Dict) and {"achieved_goal", "desired_goal"} <= set(space.spaces)
        spec = env.get_attr("spec", [0])[0]
        return goal or (spec.id if spec is not None else env_id) in rl_environments.ENV_IDS
    if isinstance(env, VecEnv):
        env = env.envs[0]
    spec = getattr(env, "spec", None)
    spec_id = spec.id if spec is not None else env_id
    return isinstance(getattr(env, "unwrapped", env), GoalEnv) or spec_id in rl_environments.ENV_IDS


# -- the legacy programmatic entry point (benchmarks) ---------------------------------------------
@dataclass
class TrainingResult:
    """What :func:`train` and :func:`run_training` measured.

    Attributes:
        evaluations: ``(env_steps, train_seconds, success_rate)`` per evaluation.
        steps_to_success: first env step count whose evaluation reached ``target`` (or None).
        seconds_to_success: training wall-clock (evaluation excluded) at that point.
        total_steps, train_seconds: what was run.
        run_dir: the run directory (``run_training``), else None.
        files: what the run wrote, by name (``final_model``, ``best_model``, ``curve``, ``video``, ...).
    """

    evaluations: list[tuple[int, float, float]]
    steps_to_success: int | None
    seconds_to_success: float | None
    total_steps: int
    train_seconds: float
    model: Any = None
    normalizer: Any = None
    run_dir: Path | None = None
    files: dict[str, Path] = field(default_factory=dict)


def _result(session: Session, **extra: Any) -> TrainingResult:
    return TrainingResult(
        evaluations=[(int(r["steps"]), float(r["train_seconds"]), float(r["success_rate"]))
                     for r in session.evaluations],
        steps_to_success=session.steps_to_success,
        seconds_to_success=session.seconds_to_success,
        total_steps=int(session.model.num_timesteps),
        train_seconds=session.train_seconds(),
        model=session.model,
        normalizer=session.normalizer,
        **extra,
    )


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
    """Train on ``env_id`` with ``config`` in memory (no run directory); evaluate every ``eval_freq`` steps.

    Args:
        target: success rate that counts as solved (for ``steps_to_success``).
        on_eval: ``callback(steps, train_seconds, success_rate)`` after each evaluation.
        save_path: where to save the final model (``.zip``, plus ``.vecnormalize.pkl``), if given.
        make_env: build the train and eval envs with this instead of ``uniros.make`` (baselines).
    """
    factory = make_env if make_env is not None else (lambda: _make_env(env_id, **config.env_kwargs))
    config = copy.deepcopy(config)
    config.progress_bar = False
    fit_learning_starts(env_id, config)
    env = make_train_env(env_id, config, make_env)
    session = Session(config, env, make_eval_env=factory, on_eval=on_eval, target=target, verbose=verbose,
                      success_info=reports_success(env, None if make_env is not None else resolve_env_id(env_id)))
    try:
        session.build()
        session.learn()
        if save_path is not None:
            path = Path(save_path)
            save_model_with_stats(session.model, session.normalizer, path if path.suffix == ".zip"
                                  else path.with_name(path.name + ".zip"))
        return _result(session)
    finally:
        session.close()


# -- runs with a run directory (uniros train) -------------------------------------------------------
def check_before_run(env_id: str, config: TrainingConfig, origin: str | None = None) -> None:
    """Refuse what cannot work before a run directory is written: an unknown env ID (with the close
    ones), an ``n_envs`` the env cannot batch (:func:`check_n_envs`), demonstrations for an env
    without a scripted policy, or with ``n_envs`` > 1.

    Raises:
        TrainingError: the message says what is wrong and what to do.
    """
    import rl_environments

    check_env_id(env_id)
    check_n_envs(env_id, config, origin)
    if config.demonstrations:
        bare = env_id.rpartition(":")[2]
        if bare not in rl_environments.MANIPULATION_ENV_IDS:
            raise TrainingConfigError(f"{config.source}: demonstrations: {config.demonstrations}, but uniros has "
                                      f"scripted demonstrations for {list(rl_environments.MANIPULATION_ENV_IDS)} only, "
                                      f"not {env_id}: set demonstrations: 0")
        if config.env_kwargs.get("ee_action_type") is False:
            raise TrainingConfigError(f"{config.source}: demonstrations are end-effector actions: drop "
                                      "ee_action_type: false from env_kwargs, or set demonstrations: 0")
        if config.n_envs > 1:
            raise TrainingConfigError(f"{config.source}: demonstrations fill one env's replay buffer: train with "
                                      "n_envs: 1, or set demonstrations: 0")


def check_env_id(env_id: str) -> str:
    """The bare ID of a registered ID or an importable ``module:ID``.

    Raises:
        TrainingError: not registered (``unknown env ..., did you mean ...``) or not importable.
    """
    import difflib

    import gymnasium as gym

    bare = resolve_env_id(env_id)
    if bare not in gym.registry:
        close = difflib.get_close_matches(bare, list(gym.registry), n=3, cutoff=0.6)
        hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
        if _ARM_ID.match(bare):
            hint += (" (an arm file's ID is registered by its file: UNIROS_ARMS=FILE, or uniros.register_arm(FILE)"
                     " in Python)")
        raise TrainingError(f"unknown env {env_id!r}{hint} (`uniros list` shows the registered IDs; your own env: "
                            "my_pkg.my_module:MyEnv-v0)")
    return bare


#: An ID an arm file would register: ``<Arm><task>Sim-v0`` or ``<Arm><task>Real-v0``.
_ARM_ID = re.compile(r"[A-Za-z][A-Za-z0-9_]*(" + "|".join(sorted(ARM_TASKS, key=len, reverse=True))
                     + r")(Sim|Real)-v0\Z")


def arm_file_of(env_id: str) -> str | None:
    """The arm file, if not one uniros ships, that registered ``env_id`` (or its simulated twin):
    a run records it (``run.json``: ``arm_file``) so that ``uniros eval`` and ``--resume`` find the ID
    in a process that has not registered it."""
    from rl_environments.arm_registry import arm_env_ids, registered_arms

    bare = env_id.rpartition(":")[2]
    for spec in registered_arms().values():
        ids = arm_env_ids(spec)
        if bare in ids or bare in {real for _, _, real in ids.values()}:
            return None if _shipped(spec.path) else str(spec.path)
    return None


def _shipped(path: Path) -> bool:
    from rl_environments import shipped_arm_file

    shipped = shipped_arm_file(path.name)
    return shipped is not None and shipped.resolve() == path.resolve()


def register_run_arm(meta: dict[str, Any], where: str, note: Callable[[str], None] | None = None) -> None:
    """Register the arm file a run was trained with (``run.json``'s ``arm_file``) when its env ID is
    not registered in this process.

    Raises:
        TrainingError: the file is gone or no longer registers the ID.
    """
    import gymnasium as gym

    from rl_environments.arm_file import ArmFileError
    from rl_environments.arm_registry import register_arm, registered_arms, unregister_arm

    path, env_id = meta.get("arm_file"), str(meta.get("env_id", "")).rpartition(":")[2]
    if not isinstance(path, str) or not path or not env_id or env_id in gym.registry:
        return
    fix = "put it back, or register the arm yourself (UNIROS_ARMS=FILE, or uniros.register_arm(FILE))"
    if not Path(path).is_file():
        raise TrainingError(f"{where}: the run's env {env_id} comes from the arm file {path}, which is gone: {fix}")
    try:
        ids = register_arm(Path(path))
    except ArmFileError as exc:
        raise TrainingError(f"{where}: the run's arm file no longer registers {env_id} ({exc}): {fix}") from None
    if env_id not in ids:  # the file names another arm now: take back what it registered
        for name, spec in list(registered_arms().items()):
            if spec.path == Path(path).resolve():
                unregister_arm(name)
        raise TrainingError(f"{where}: the run's arm file {path} no longer registers {env_id} (it registers "
                            f"{', '.join(ids[:2])}, ...): {fix}")
    if note is not None:
        note(f"registered the arm file {path} this run was trained with (run.json)")


def note_updates_per_env_step(config: TrainingConfig) -> str | None:
    """A note when ``n_envs`` > 1 gives fewer gradient updates per env step than one env would.

    SB3 counts ``gradient_steps`` per vector step (per ``train_freq`` rollout); ``-1`` makes as
    many as env steps were collected, so one update per env step at any ``n_envs`` (the shipped
    configs use it).
    """
    from uniros.algorithms import is_off_policy

    grads = config.algo_params.get("gradient_steps", 1)
    if config.n_envs <= 1 or not is_off_policy(config.algorithm) or not isinstance(grads, int) or grads < 0:
        return None
    return (f"gradient_steps {grads} with {config.n_envs} envs makes {grads} update(s) per {config.n_envs} env steps "
            f"({grads / config.n_envs:g} per env step, one env gets {grads}); gradient_steps: -1 keeps one per env "
            "step (SB3: as many as env steps collected)")


def start_run(env_id: str, config: TrainingConfig, *, output: str | Path = "runs", name: str | None = None,
              command: list[str] | None = None) -> RunDir:
    """Create the run directory (locked by this process) and write the resolved config and ``run.json``.

    What cannot work is refused first (:func:`check_before_run`), and HER's ``learning_starts`` is
    raised for ``n_envs`` (:func:`fit_learning_starts`), so ``config.yaml`` holds what the run trains
    with. If the run then fails before it starts learning (:func:`run_training`), the directory is
    removed again: a refused run leaves nothing.
    """
    if name is not None:
        check_run_name(name)
    check_before_run(env_id, config)
    changed = fit_learning_starts(env_id, config)
    if changed:
        _logger.warning("%s", changed)
    run = RunDir.create(output, name, env_id, config.algorithm)
    run.created_here = True
    try:
        save_training_config(config, run.config)
        run.update_meta(env_id=env_id, algorithm=config.algorithm, env_kwargs=config.env_kwargs, status="created",
                        steps=0, train_seconds=0.0, command=command or [],
                        started_with=config.to_dict()["model_params"], arm_file=arm_file_of(env_id))
    except OSError as exc:
        run.discard()
        full = disk_full_error(exc, Path(output), "nothing was kept: free space, then start the run again")
        if full is not None:
            raise full from None
        raise
    return run


def open_run(run_dir: str | Path) -> tuple[RunDir, str, TrainingConfig]:
    """An existing run directory, locked by this process, its env ID and its resolved config (for
    ``--resume``); stale temporary files of killed writes are removed.

    Raises:
        RunDirError: not a run directory, or another process writes it.
        TrainingConfigError: its ``config.yaml`` is invalid, or edited in a way a resumed run cannot
            honour (:func:`uniros.resume.resume_overrides`).
    """
    from uniros.resume import resume_overrides, started_config

    run = RunDir.open(run_dir)
    run.lock()
    try:
        remove_stale_temporaries(run.root)
        meta = run.read_meta()
        config = load_training_config(run.config)
        started = started_config(meta, str(run.config))
        if started is not None:
            resume_overrides(started, config)
        else:  # runs of earlier versions: the env kwargs of run.json
            config.env_kwargs = dict(meta.get("env_kwargs", config.env_kwargs))
        if "env_id" not in meta:
            raise RunDirError(f"{run.meta} names no env_id: not a run `uniros train` wrote")
        register_run_arm(meta, str(run.meta), lambda line: _logger.warning("%s", line))
    except BaseException:
        run.release()
        raise
    return run, str(meta["env_id"]), config


def run_training(
    run: RunDir,
    env_id: str,
    config: TrainingConfig,
    *,
    resume: bool = False,
    target: float = 0.9,
    on_eval: Callable[[int, float, float], None] | None = None,
    verbose: int = 0,
    on_note: Callable[[str], None] | None = None,
) -> TrainingResult:
    """Train into ``run`` (new, or ``resume`` from its newest usable checkpoint), then write the final
    model, the learning curve and the video.

    A resumed run takes the newest checkpoint whose files all load (model, replay buffer,
    statistics), says which it skipped and why (``on_note``, default: a warning), and starts again
    from step 0 when there is none; ``run.json`` says ``failed`` (and why) when training raises.
    A new run that fails before it learns leaves no directory.

    Raises:
        TrainingInterrupted: Ctrl-C or SIGTERM; a checkpoint was saved first.
        TrainingError: bad config, env or files (clear message).
    """
    from uniros.reports import plot_learning_curve

    note = on_note or (lambda text: _logger.warning("%s", text))
    paths = Paths(checkpoints=run.checkpoints, prefix=config.save_prefix, logs=run.tensorboard,
                  monitor=run.monitor, evaluations=run.evaluations, best_model=run.best_model, meta=run.meta)
    run.lock()
    session = None
    learning = False
    try:
        with sigterm_as_interrupt():
            changed = fit_learning_starts(env_id, config)
            if changed:
                note(changed)
            env = make_train_env(env_id, config)
            session = Session(config, env, make_eval_env=_eval_factory(env_id, config), paths=paths,
                              on_eval=on_eval, target=target, verbose=verbose,
                              success_info=reports_success(env, resolve_env_id(env_id)))
            if resume:
                _resume_session(session, run, note)
            else:
                session.build()
            check_disk_for_run(run.root, config, session.model)
            run.update_meta(status="running", device=str(session.model.device))
            learning = True
            session.learn()
            save_model_with_stats(session.model, session.normalizer, run.final_model)
            session.checkpoint()
            run.update_meta(status="finished", steps=int(session.model.num_timesteps),
                            train_seconds=round(session.train_seconds(), 3))
            files = {"run_dir": run.root, "final_model": run.final_model, "config": run.config,
                     "tensorboard": run.tensorboard, "monitor": run.monitor, "checkpoints": run.checkpoints}
            if run.best_model.is_file():
                files["best_model"] = run.best_model
            if session.evaluations:
                files["evaluations"] = run.evaluations
                plot_learning_curve(session.evaluations, run.curve, title=f"{env_id} {config.algorithm.upper()}",
                                    monitor_csv=run.monitor / "train.monitor.csv")
                files["curve"] = run.curve
            return _result(session, run_dir=run.root, files=files)
    except TrainingInterrupted:
        raise
    except BaseException as exc:
        if session is not None:
            session.close()
            session = None
        discard = not learning and not resume and getattr(run, "created_here", False)
        full = disk_full_error(exc, run.root, "nothing was kept: free space, then start the run again" if discard
                               else lambda: run_state_after_disk_full(run.root, _last_checkpoint_steps(run)))
        if discard:
            run.discard()  # nothing learnt: a refused run leaves nothing
        elif learning and not isinstance(exc, KeyboardInterrupt):
            try:
                run.update_meta(status="failed", error=f"{type(exc).__name__}: {exc}"[:500])
            except OSError:  # the disk is full: run.json stays as it was (written atomically)
                if full is None:
                    raise
        if full is not None:
            raise full from None
        raise
    finally:
        if session is not None:
            session.close()
        run.release()  # the run is written no more: another process (or call) may resume it


def _last_checkpoint_steps(run: RunDir) -> int | None:
    from uniros.checkpoints import latest_checkpoint

    found = latest_checkpoint(run.checkpoints)
    return found[0].steps if found else None


def _eval_factory(env_id: str, config: TrainingConfig) -> Callable[[], Any]:
    """Builds one env of ``env_id`` (evaluation, demonstrations); ``.spec`` gives its episode limit."""
    import gymnasium as gym

    def factory() -> Any:
        return make_env(env_id, **config.env_kwargs)

    bare = resolve_env_id(env_id)
    factory.spec = gym.spec(bare) if bare in gym.registry else None  # type: ignore[attr-defined]
    return factory


def _resume_session(session: Session, run: RunDir, note: Callable[[str], None]) -> None:
    """Build ``session`` from the run's newest usable checkpoint (see :mod:`uniros.resume`), or
    from scratch when none is."""
    from uniros.algorithms import is_off_policy
    from uniros.reports import read_evaluations, write_evaluations
    from uniros.resume import choose_checkpoint, resume_overrides, started_config

    config = session.config
    meta = run.read_meta()
    started = started_config(meta, str(run.config))
    overrides = resume_overrides(started, config) if started is not None else {}
    env = session.env
    choice = choose_checkpoint(run.checkpoints, config.save_prefix, config,
                               observation_space=env.observation_space, action_space=env.action_space,
                               needs_buffer=is_off_policy(config.algorithm))
    for line in choice.report():
        note(line)
    if choice.chosen is None:
        kept = run.set_aside_for_restart()
        unusable = run.checkpoints / "unusable"
        note(f"no usable checkpoint in {run.checkpoints}"
             + (f" (the unusable ones are in {unusable})" if unusable.is_dir() and any(unusable.iterdir()) else "")
             + ": starting the run again from step 0"
             + (f"; what the earlier attempt wrote (models, evaluations, logs) is kept in {kept}" if kept else ""))
        run.update_meta(steps=0, train_seconds=0.0, resumed_from=None, resumed_without_buffer=False)
        session.build()
        return
    ckpt = choice.chosen.checkpoint
    rows = [r for r in read_evaluations(run.evaluations) if r.get("steps", 0) <= ckpt.steps]
    if choice.skipped:  # evaluations after the checkpoint resumed from belong to steps that are redone
        write_evaluations(run.evaluations, rows)
    session.evaluations = rows
    seconds = float(meta.get("train_seconds", 0.0))
    if int(meta.get("steps", ckpt.steps)) > ckpt.steps and rows:
        seconds = float(rows[-1].get("train_seconds", seconds))
    session.prior_seconds = seconds
    session.restore_success(rows)
    if overrides:
        note(f"hyperparameters changed since the run started, applied to the resumed model: {overrides}")
    session.build(resume=ckpt, buffer=choice.chosen.buffer, load_kwargs=overrides)
    run.update_meta(resumed_from=ckpt.model.name, resumed_without_buffer=choice.without_buffer)


def record_run_video(run: RunDir, env_id: str, config: TrainingConfig, *, episodes: int | None = None) -> Path:
    """Record the best model (else the final one) of ``run`` as ``best_model.mp4``."""
    from uniros.reports import record_video

    model_path = run.best_model if run.best_model.is_file() else run.final_model
    env = make_env(env_id, **config.env_kwargs)
    try:
        model, normalizer = load_for_eval(model_path, env, device=config.device)
    finally:
        env.close()
    target = run.video if model_path == run.best_model else run.root / "final_model.mp4"
    record_video(model, lambda **kw: make_env(env_id, **{**config.env_kwargs, **kw}), target,
                 episodes=episodes or config.video_episodes, normalizer=normalizer, seed=EVAL_SEED)
    return target


# -- loading for evaluation ------------------------------------------------------------------------
def find_normalizer(model_path: Path) -> Path | None:
    """The ``VecNormalize`` statistics of a model: uniros' ``<model>.vecnormalize.pkl``, or rl-zoo3's
    ``vecnormalize.pkl`` (``<run>/<env id>/vecnormalize.pkl`` next to ``<run>/<env id>.zip``)."""
    own = normalizer_path(model_path)
    folder = model_path.parent
    candidates = [own, folder / model_path.stem / "vecnormalize.pkl", folder / "vecnormalize.pkl"]
    candidates += sorted(folder.glob("*/vecnormalize.pkl"))
    return next((c for c in candidates if c.is_file()), None)


def resolve_model_path(model: str | Path) -> Path:
    """A model ``.zip`` from what a user typed: a file, a file without ``.zip``, or a run directory.

    Raises:
        ModelFileError: nothing there (the message says what was looked for).
    """
    path = Path(model)
    if path.is_dir():
        for name in ("best_model.zip", "final_model.zip"):
            if (path / name).is_file():
                return path / name
        zips = sorted(path.glob("*.zip"))
        if len(zips) == 1:
            return zips[0]
        raise ModelFileError(f"{str(path)!r} is a directory without best_model.zip or final_model.zip"
                             + (f"; models in it: {[z.name for z in zips]}" if zips else ""))
    if path.is_file():
        return path
    if path.suffix != ".zip" and path.with_name(path.name + ".zip").is_file():
        return path.with_name(path.name + ".zip")
    raise ModelFileError(f"model file {str(path)!r} not found")


def trained_env_id(model_path: Path) -> str | None:
    """The env ID a model was trained on, from its run's ``run.json`` (or ``<model>.env.json``)."""
    for meta in (model_path.parent / "run.json", model_path.with_suffix(".env.json")):
        try:
            env_id = json.loads(meta.read_text()).get("env_id")
        except (OSError, ValueError, AttributeError):
            continue
        if isinstance(env_id, str) and env_id:
            return env_id
    return None


def saved_env_kwargs(model_path: Path, env_id: str | None = None) -> dict[str, Any]:
    """The env kwargs a model was trained with: uniros' run.json / .env.json, or rl-zoo3's args.yml.

    None when the model was trained on another env than ``env_id`` (its kwargs may not apply).
    """
    for meta in (model_path.parent / "run.json", model_path.with_suffix(".env.json")):
        if meta.is_file():
            try:
                data = json.loads(meta.read_text())
            except ValueError:
                continue
            trained_on = str(data.get("env_id", "")).rpartition(":")[2]
            kwargs = dict(data.get("env_kwargs") or {})
            target = None if env_id is None else env_id.rpartition(":")[2]
            if target is not None and trained_on and trained_on != target:
                if SIM_TO_REAL.get(trained_on) != target:
                    return {}
                # The Real twin of the training env: the same task options, none of the simulation's
                # (its transport included: a robot is reached over the user's Zenoh graph).
                return {k: v for k, v in kwargs.items() if k not in SIMULATION_KNOBS and k != "transport"}
            return kwargs
    for folder in [model_path.parent / model_path.stem, *sorted(model_path.parent.glob("*/"))]:
        args = folder / "args.yml"
        if args.is_file():
            data = _zoo_yaml(args)
            kwargs = data.get("env_kwargs") if isinstance(data, dict) else None
            return dict(kwargs or {})
    return {}


def _zoo_yaml(path: Path) -> Any:
    """rl-zoo3's args.yml/config.yml (OrderedDicts dumped as python tags), read without running code."""
    import yaml

    class Loader(yaml.SafeLoader):
        pass

    def ordered(loader: Any, node: Any) -> dict[str, Any]:
        seq = loader.construct_sequence(node.value[0], deep=True) if node.value else []
        return {k: v for k, v in seq}

    Loader.add_constructor("tag:yaml.org,2002:python/object/apply:collections.OrderedDict", ordered)
    Loader.add_multi_constructor("tag:yaml.org,2002:python/", lambda loader, suffix, node: None)
    try:
        data = yaml.load(path.read_text(), Loader=Loader)  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError:
        return {}
    return dict(data) if isinstance(data, dict) else (dict(data) if isinstance(data, list) else {})


def load_for_eval(model_path: Path, env: Any, *, algorithm: str | None = None,
                  device: str | None = None) -> tuple[Any, Any]:
    """Load a model and its normalisation statistics for ``env`` (uniros' or rl-zoo3's layout);
    the model onto ``device`` (``auto`` by default, :mod:`uniros.devices`), the statistics (numpy,
    applied to observations before they reach the device) as they are.

    Returns:
        ``(model, normalizer)``; ``normalizer`` is a frozen ``VecNormalize`` or ``None``.
    """
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    normalizer = None
    stats = find_normalizer(model_path)
    from uniros.image_spaces import images_channel_first

    venv = images_channel_first(DummyVecEnv([lambda: env]))
    if stats is not None:
        try:
            normalizer = VecNormalize.load(str(stats), venv)
        except (AssertionError, ValueError) as exc:
            raise ModelFileError(f"{stats} does not fit this env ({exc}); "
                                 "evaluate on the env the model was trained on") from exc
        except Exception as exc:
            raise ModelFileError(f"{stats} cannot be read ({type(exc).__name__}: {exc})") from exc
        normalizer.training = False
        normalizer.norm_reward = False
    # HER models need an env to rebuild their replay buffer, even for prediction.
    model = load_model(model_path, normalizer if normalizer is not None else venv, algorithm=algorithm, device=device)
    return model, normalizer


__all__ = [
    "ALGORITHMS",
    "EVAL_SEED",
    "ModelFileError",
    "RunDir",
    "RunDirError",
    "TrainingConfig",
    "TrainingConfigError",
    "TrainingError",
    "TrainingInterrupted",
    "TrainingResult",
    "build_model",
    "check_before_run",
    "check_env_id",
    "default_config_for",
    "evaluate",
    "find_normalizer",
    "format_success",
    "load_for_eval",
    "load_training_config",
    "make_env",
    "note_updates_per_env_step",
    "open_run",
    "parse_training_config",
    "record_run_video",
    "resolve_env_id",
    "resolve_model_path",
    "run_training",
    "start_run",
    "train",
    "trained_env_id",
    "wilson_interval",
]
