"""Training runs: Stable-Baselines3 agents on uniros envs from one YAML file.

One implementation (:mod:`uniros.trainer`) serves ``uniros train``, :func:`train` and the
sb3_ros_support-style classes of :mod:`uniros.sb3`. The YAML is sb3_ros_support's or FRobs_RL's
format (:mod:`uniros.train_config`); a run writes a run directory (:mod:`uniros.run_dir`) with
TensorBoard logs, monitor CSVs, checkpoints, the best and final models, a learning-curve plot and
a video; Ctrl-C or SIGTERM saves a checkpoint that :func:`run_training` resumes. The envs a run
trains on are made by :mod:`uniros.run_envs`; the models it saves are read back by :mod:`uniros.model_files`.

Configs shipped with uniros sit in ``config/training/`` (installed as
``rl_environments.config.training``), one per env ID; see :func:`default_config_for`.
"""

from __future__ import annotations

import copy
import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from uniros.checkpoints import remove_stale_temporaries, save_model_with_stats
from uniros.evaluation import EVAL_SEED, evaluate, format_success, wilson_interval
from uniros.interrupts import TrainingInterrupted, sigterm_as_interrupt

# Re-exported: the envs of a run (uniros.run_envs) and the model files (uniros.model_files) have modules
# of their own, but saved user code and docs import their public names from uniros.training.
from uniros.model_files import (  # noqa: F401
    find_normalizer,
    load_for_eval,
    resolve_model_path,
    saved_env_kwargs,
    trained_env_id,
)
from uniros.resources import check_disk_for_run, disk_full_error, run_state_after_disk_full
from uniros.run_dir import RunDir, RunDirError, check_run_name
from uniros.run_envs import (
    arm_file_of,
    check_env_id,
    check_n_envs,
    fit_learning_starts,
    make_env,
    make_train_env,
    register_run_arm,
    reports_success,
    resolve_env_id,
)
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
)

_logger = logging.getLogger(__name__)


_make_env = make_env  # ``train`` has a parameter of that name


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
    ones), an ``n_envs`` the env cannot batch (:func:`~uniros.run_envs.check_n_envs`), demonstrations for an env
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
    if config.demos:
        from uniros.demonstrations_io import DemonstrationsError, check_dataset_for

        if config.n_envs > 1:
            raise TrainingConfigError(f"{config.source}: --demos fills one env's replay buffer: train with n_envs: 1")
        try:
            check_dataset_for(config.demos, env_id)
        except DemonstrationsError as exc:
            raise TrainingConfigError(f"--demos: {exc}") from None


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
    raised for ``n_envs`` (:func:`~uniros.run_envs.fit_learning_starts`), so ``config.yaml`` holds what the run trains
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
    init_from: Path | None = None,
    init_buffer: Path | None = None,
) -> TrainingResult:
    """Train into ``run`` (new, or ``resume`` from its newest usable checkpoint), then write the final
    model, the learning curve and the video. ``init_from``: a saved model a new run starts from (its
    weights; the config's hyperparameters, a fresh replay buffer, step 0), recorded in ``run.json``;
    ``init_buffer``: a replay buffer file it starts with instead (recorded too).

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
                session.build(init=init_from, init_buffer=init_buffer)
                if init_from is not None:
                    run.update_meta(init_from=str(init_from), init_buffer=str(init_buffer) if init_buffer else None)
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
        init, init_buffer = meta.get("init_from"), meta.get("init_buffer")  # a warm start starts again as it did
        session.build(init=Path(init) if isinstance(init, str) and init else None,
                      init_buffer=Path(init_buffer) if isinstance(init_buffer, str) and init_buffer else None)
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
