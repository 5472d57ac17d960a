"""The ``uniros`` command: ``train``, ``eval``, ``list``, ``doctor``, ``sim``, ``new``, ``arm add``, ``arm check``,
``export`` and ``deploy``.

Each subcommand is a small function taking parsed arguments and returning an exit code; a group of
subcommands adds its parser with a ``_<name>_parser(sub)`` function called from :func:`build_parser`.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from multiros.excerpt import excerpt


def _cmd_list(args: argparse.Namespace) -> int:
    import rl_environments
    from uniros.train_config import shipped_config_ids

    goal = set(rl_environments.GOAL_ENV_IDS) | set(rl_environments.REAL_GOAL_ENV_IDS)
    configs = set(shipped_config_ids())
    for title, specs in (("simulated (the simulation node; run anywhere); config: `uniros train ID` has a shipped "
                          "training config", rl_environments.ENV_SPECS),
                         ("real (a ros2_control robot or a stand-in: docs/real_robots.md)",
                          rl_environments.REAL_ENV_SPECS)):
        print(f"# {title}")
        for env_id, entry_point in specs.items():
            print(f"{env_id:32s} {'goal' if env_id in goal else 'plain':5s} {'config' if env_id in configs else '':6s} "
                  f"{entry_point}")
    return 0


def _env_overrides(args: argparse.Namespace) -> dict[str, object]:
    overrides: dict[str, object] = {}
    if args.sim_mode:
        overrides["sim_mode"] = args.sim_mode
    if args.transport:
        overrides["transport"] = args.transport
    return overrides


def _note(text: str) -> None:
    print(f"note: {text}", file=sys.stderr, flush=True)


def _shared_graph_note(env_id: str, env_kwargs: dict[str, object]) -> str | None:
    """Which ROS 2 graph a run joins when it leaves the process (an existing node, Zenoh, a robot),
    through the transport it will use, with a pointer to per-user domains and routers when it is
    the machine's default one."""
    import os

    import rl_environments
    from multiros.ros.transport import wire_transport
    from multiros.ros.transport.rclpy.loader import RMW_ENV
    from multiros.ros.transport.zenoh.config import DEFAULT_ROUTER_ENDPOINT, ROUTER_ENV

    real = env_id.rpartition(":")[2] in rl_environments.REAL_ENV_IDS
    mode = env_kwargs.get("sim_mode", "composed")
    shared = real or mode == "existing" or (env_kwargs.get("transport") == "zenoh" and mode == "composed")
    if not shared:
        return None
    explicit = env_kwargs.get("transport")
    transport = wire_transport(explicit if isinstance(explicit, str) else None, prefer_rclpy=real or mode == "existing")
    domain = os.environ.get("ROS_DOMAIN_ID", "").strip()
    where = f"{env_id} joins the ROS 2 graph of domain {domain or '0 (ROS_DOMAIN_ID unset)'}"
    if transport == "rclpy":  # DDS: no router; how far discovery reaches is what matters
        rmw = os.environ.get(RMW_ENV, "").strip()
        reach = os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "").strip() or "ROS 2's default (SUBNET on Jazzy)"
        text = (f"{where} through rclpy on {rmw or 'its default middleware'} ({RMW_ENV}), DDS discovery range "
                f"{reach}: everyone it reaches on that domain shares it (docs/ros2_system.md, What protects a "
                "node on DDS)")
        if domain in ("", "0"):
            text += "; set ROS_DOMAIN_ID per user (docs/pitfalls.md, Shared machines)"
        return text
    router = os.environ.get(ROUTER_ENV) or DEFAULT_ROUTER_ENDPOINT
    text = f"{where} through the Zenoh router {router}"
    if domain in ("", "0") and router == DEFAULT_ROUTER_ENDPOINT:
        text += ("; every user of this machine with the defaults shares it: set ROS_DOMAIN_ID and "
                 f"{ROUTER_ENV} per user (docs/pitfalls.md, Shared machines)")
    return text


def _init_buffer_of(init_from: str | None) -> Path:
    """The replay buffer ``--init-buffer`` names: that of the newest checkpoint of the ``--init-from`` run."""
    from uniros.checkpoints import newest_replay_buffer
    from uniros.training import TrainingError

    if not init_from or not Path(init_from).is_dir():
        raise TrainingError("--init-buffer takes the replay buffer of the --init-from run: give --init-from a run "
                            "directory")
    try:
        return newest_replay_buffer(Path(init_from) / "checkpoints").resolve()
    except ValueError as exc:
        raise TrainingError(f"--init-buffer: {exc} (the run's config kept none: keep_replay_buffers)") from None


def _cmd_train(args: argparse.Namespace) -> int:
    from uniros.run_dir import check_run_name
    from uniros.run_envs import check_env_id
    from uniros.training import TrainingError, default_config_for, load_training_config, open_run

    if args.resume:
        if args.config or args.name or args.init_from or args.init_buffer:
            raise TrainingError("--resume continues a run with its own config.yaml (and the model it started from): "
                                "drop --config, --name, --init-from and --init-buffer")
        run, env_id, config = open_run(args.resume)  # locked from here on: a second --resume is refused
        try:
            return _train(args, run, env_id, config)
        finally:
            run.release()
    if not args.env_id:
        raise TrainingError("give an env ID (e.g. RX200ReacherGoalSim-v0 or my_pkg.my_module:MyEnv-v0) "
                            "or --resume RUN_DIR")
    check_env_id(args.env_id)  # a user's module:ID is imported (and checked) before anything is written
    if args.name is not None:
        check_run_name(args.name)
    config = load_training_config(args.config, steps=args.steps) if args.config else default_config_for(args.env_id)
    return _train(args, None, args.env_id, config)


def _train(args: argparse.Namespace, run: Any, env_id: str, config: Any) -> int:
    """``uniros train`` once the config is known: ``run`` is the resumed run (locked), or ``None``."""
    from uniros.evaluation import EVAL_SEED, format_success
    from uniros.model_files import load_for_eval
    from uniros.run_envs import fit_learning_starts, make_env
    from uniros.training import (
        TrainingError,
        TrainingInterrupted,
        check_before_run,
        evaluate,
        note_updates_per_env_step,
        record_run_video,
        run_training,
        start_run,
    )

    if args.resume and args.env_id and args.env_id != env_id:
        raise TrainingError(f"{run.root} is a run on {env_id!r}, not {args.env_id!r}")
    if args.steps is not None:
        config.training_steps = args.steps
    if getattr(args, "demos", None):
        from uniros.algorithms import is_off_policy

        if not is_off_policy(config.algorithm):
            raise TrainingError(f"--demos go into a replay buffer: {config.algorithm} has none (train an off-policy "
                                "algorithm such as sac)")
        config.demos = str(Path(args.demos).resolve())
    _choose_device(args, config)
    if args.seed is not None:
        config.seed = args.seed
    if args.n_envs is not None:
        if args.n_envs < 1:
            raise TrainingError(f"--n-envs must be at least 1, got {args.n_envs}")
        if args.resume and args.n_envs != config.n_envs:
            raise TrainingError(f"{run.root} was started with n_envs: {config.n_envs}, and a resumed run keeps it "
                                "(an off-policy algorithm's replay buffer holds that many envs' transitions); "
                                "drop --n-envs")
        config.n_envs = args.n_envs
    if args.pin_workers is not None:
        config.pin_workers = args.pin_workers
    config.env_kwargs.update(_env_overrides(args))
    check_before_run(env_id, config, None if args.n_envs is None else f"--n-envs {args.n_envs}")
    for text in (note_updates_per_env_step(config), fit_learning_starts(env_id, config),
                 _shared_graph_note(env_id, config.env_kwargs)):
        if text:
            _note(text)
    config.progress_bar = config.progress_bar and not args.no_progress and sys.stderr.isatty()
    init_from = init_buffer = None
    if getattr(args, "init_from", None):  # found now (run.json records it); its fit is checked as the model is built
        from uniros.model_files import resolve_model_path

        init_from = resolve_model_path(args.init_from).resolve()
    if getattr(args, "init_buffer", False):
        init_buffer = _init_buffer_of(args.init_from)
    if not args.resume:
        run = start_run(env_id, config, output=args.output, name=args.name, command=["uniros", *sys.argv[1:]])
    print(f"{'resuming' if args.resume else 'training'} {config.algorithm.upper()}{' + HER' if config.use_her else ''} "
          f"on {env_id}{f' x {config.n_envs} envs' if config.n_envs > 1 else ''} for {config.training_steps} steps "
          f"(config: {config.source})", flush=True)
    print(f"run directory: {run.root}", flush=True)

    def report(steps: int, seconds: float, rate: float) -> None:
        print(f"  steps {steps:6d}  train time {seconds:7.1f} s  eval success "
              f"{format_success(rate, config.eval_episodes)}", flush=True)

    try:
        result = run_training(run, env_id, config, resume=bool(args.resume), target=args.target, on_eval=report,
                              on_note=_note, init_from=init_from, init_buffer=init_buffer)
    except TrainingInterrupted as exc:
        print(f"\n{exc}", file=sys.stderr)
        print(f"resume with: uniros train --resume {run.root}", file=sys.stderr)
        return exc.exit_code
    print(f"trained {result.total_steps} steps in {result.train_seconds:.1f} s on {result.model.device}")
    if result.steps_to_success is not None:
        print(f"first eval success >= {args.target}: {result.steps_to_success} steps, "
              f"{result.seconds_to_success:.1f} s of training")
    elif result.evaluations:
        print(f"eval success never reached {args.target}")
    model_path = result.files.get("best_model", result.files["final_model"])
    if args.eval_episodes > 0:
        env = make_env(env_id, **config.env_kwargs)
        try:
            model, normalizer = load_for_eval(model_path, env, device=config.device)
            stats = evaluate(model, env, args.eval_episodes, seed=EVAL_SEED, normalizer=normalizer)
        finally:
            env.close()
        print(f"final evaluation of {model_path.name} over {args.eval_episodes} episodes: success rate "
              f"{format_success(stats['success_rate'], args.eval_episodes)} (95% CI), mean return "
              f"{stats['mean_return']:.2f}, mean length {stats['mean_length']:.1f} "
              f"(`uniros eval {run.root} --episodes {args.eval_episodes}` plays the same episodes)")
    if config.video and not args.no_video:
        try:
            result.files["video"] = record_run_video(run, env_id, config)
        except Exception as exc:  # the run is complete without it: say why there is no video
            print(f"no video: {type(exc).__name__}: {exc} (headless rendering needs MUJOCO_GL=egl or osmesa)",
                  file=sys.stderr)
    print("files:")
    for label, path in result.files.items():
        print(f"  {label:12s} {path}")
    return 0


def _choose_device(args: argparse.Namespace, config: Any) -> None:
    """Put ``--device`` into the config (a new run's config.yaml records it; a resumed run keeps its
    own unless ``--device`` is given), and refuse a GPU that is not there before anything is written."""
    from uniros.devices import check_device, resolve_device

    if args.device is not None:
        config.algo_params["device"] = check_device(args.device, "--device")
    elif not args.resume:
        config.algo_params.setdefault("device", "auto")
    where = "--device" if args.device is not None else f"{config.source}: {config.algorithm}_params.device"
    resolve_device(config.device, None, where)


def _cmd_eval(args: argparse.Namespace) -> int:
    from uniros.eval_target import eval_target
    from uniros.evaluation import format_success
    from uniros.model_files import load_for_eval, saved_env_kwargs
    from uniros.run_envs import make_env
    from uniros.training import evaluate

    env_id, model_path = eval_target(args.env_id, args.model, args.env, _note)
    kwargs = {**saved_env_kwargs(model_path, env_id), **_env_overrides(args)}
    note = _shared_graph_note(env_id, kwargs)
    if note:
        _note(note)
    env = make_env(env_id, **kwargs)
    try:
        from uniros.model_spaces import SpaceMismatchError, check_model_spaces

        try:
            check_model_spaces(model_path, env, env_id)
        except SpaceMismatchError as exc:
            print(exc, file=sys.stderr)
            return 2
        model, normalizer = load_for_eval(model_path, env, algorithm=args.algo, device=args.device)
        stats = evaluate(model, env, args.episodes, seed=args.seed, normalizer=normalizer)
    finally:
        env.close()
    print(f"{env_id}: success rate {format_success(stats['success_rate'], args.episodes)} (95% CI) over "
          f"{args.episodes} episodes (seeds {args.seed}-{args.seed + args.episodes - 1}), "
          f"mean return {stats['mean_return']:.2f}, mean length {stats['mean_length']:.1f}"
          + ("" if normalizer is None else " (observations normalised with the saved statistics)"))
    return 0


def _cmd_doctor(args: argparse.Namespace) -> int:
    from uniros.doctor import main as doctor_main

    return doctor_main(args)


def _cmd_sim(args: argparse.Namespace) -> int:
    from multiros.sim.program import main as sim_main

    return sim_main(args.sim_args)


def _cmd_new(args: argparse.Namespace) -> int:
    from uniros.templates_cli import create_from_templates

    created = create_from_templates(args.name, Path(args.directory), goal=args.goal, style=args.style)
    for path in created:
        print(f"created {path}")
    return 0


# -- uniros arm add (issue 34) ------------------------------------------------------------------------
def _cmd_arm_add(args: argparse.Namespace) -> int:
    from multiros.hardware.robot_spec import parse_xacro_args
    from rl_environments.arm_add import add_arm

    xacro_args = parse_xacro_args(args.xacro_arg)
    if not args.no_check:
        print(f"drafting {args.name} and trying it with the scripted policies (seconds to a minute) ...", flush=True)
    path, ids, draft = add_arm(args.uri, args.name, xacro_args=xacro_args, output=args.output, force=args.force,
                               check=not args.no_check)
    print(f"wrote {path} (and {path.parent / args.name}/): check the values marked 'guessed'")
    print(f"servo settle check: largest tracking error {draft.settle_error:.4f} rad")
    if draft.sections.get("gripper") is None:  # why there is no push / pick-and-place, in one line
        print(f"reach only: {draft.comments.get('gripper', 'no gripper')}")
    if draft.check is not None:
        print(f"scripted check ({draft.check.seconds:.0f} s):")
        for task in draft.check.tasks:
            print(f"- {task.line()}")
    print(f"registered (uniros.register_arm({str(path)!r}), or UNIROS_ARMS={path}):")
    for env_id in ids:
        print(f"  {env_id}")
    return 0


def _arm_parser(sub: Any) -> None:
    arm = sub.add_parser("arm", help="arms as data: write an arm file from a robot description")
    arm_sub = arm.add_subparsers(dest="arm_command", required=True)
    p = arm_sub.add_parser("add", help="inspect a URDF/xacro description and write NAME.yaml (an arm file)")
    p.add_argument("uri", help="package://pkg/urdf/robot.urdf.xacro (found through AMENT_PREFIX_PATH) or a path")
    p.add_argument("--xacro-arg", action="append", default=[], metavar="NAME:=VALUE",
                   help="a xacro argument (repeat; NAME=VALUE too)")
    p.add_argument("--name", required=True, help="the arm's name, the IDs' prefix (MyArm: MyArmReacherSim-v0, ...)")
    p.add_argument("--output", default=".", help="where NAME.yaml and NAME/ go (default: %(default)s)")
    p.add_argument("--force", action="store_true", help="replace an existing NAME.yaml and NAME/")
    p.add_argument("--no-check", action="store_true",
                   help="write the file without trying it with the scripted policies first")
    p.set_defaults(func=_cmd_arm_add)
    p = arm_sub.add_parser("check", help="try an arm file's IDs with the scripted policies (reach, push, "
                                         "pick-and-place)")
    p.add_argument("file", help="the arm file (NAME.yaml)")
    p.add_argument("--seeds", type=int, default=3, help="episodes per task, seeds 0.. (default: %(default)s)")
    p.set_defaults(func=_cmd_arm_check)


def _cmd_arm_check(args: argparse.Namespace) -> int:
    from rl_environments.arm_check import PASS_RATE, check_arm

    if args.seeds < 1:
        raise ValueError(f"--seeds must be at least 1, got {args.seeds}")
    result = check_arm(args.file, seeds=range(args.seeds))
    for task in result.tasks:
        print(task.line())
    verdict = "passed" if result.passed else f"FAILED (each task needs {PASS_RATE:.0%} of its seeds)"
    print(f"{result.name}: {verdict} in {result.seconds:.0f} s")
    return 0 if result.passed else 1


# -- uniros export / uniros deploy (issue 51) ---------------------------------------------------------
def _cmd_export(args: argparse.Namespace) -> int:
    from uniros.policy_export import export_run

    result = export_run(args.run, args.output, model=args.model)
    meta = result.metadata
    inputs = ", ".join(f"{i.name} {list(i.shape)}" for i in meta.inputs)
    print(f"wrote {result.path}: {meta.algorithm.upper()} policy of {meta.env_id} (inputs {inputs}; action "
          f"{list(meta.action_shape)}; observation normalisation {'inside' if meta.normalized else 'none'}), "
          f"{meta.exporter}, opset {meta.opset}")
    print(f"checked: onnxruntime's actions equal SB3's predict(deterministic=True) on {result.checked} sampled "
          f"observations (largest difference {result.max_error:.2g})")
    return 0


def _cmd_deploy(args: argparse.Namespace) -> int:
    from uniros.deploy import deploy

    return deploy(args.target, env_id=args.env, arm=args.arm, episodes=args.episodes, transport=args.transport,
                  router=args.router, say=lambda text: print(text, flush=True), note=_note)


def _deploy_parsers(sub: Any) -> None:
    p = sub.add_parser("export", help="write a run's policy as ONNX (normalisation and action scaling inside)")
    p.add_argument("run", help="a run directory (the one `uniros train` printed)")
    p.add_argument("--output", help="the .onnx file (default: RUN/<model>_model.onnx)")
    p.add_argument("--model", choices=["best", "final"], default="best",
                   help="which model of the run (default: %(default)s; final when the run has no best model)")
    p.set_defaults(func=_cmd_export)
    p = sub.add_parser("deploy", help="run an exported policy on a robot through its Real env (onnxruntime only)")
    p.add_argument("target", metavar="RUN|MODEL.onnx", help="a run directory with an exported policy, or the .onnx")
    p.add_argument("--env", help="the Real ID to drive (default: the Real twin of the policy's ID)")
    p.add_argument("--arm", metavar="FILE", help="the arm file that registers the ID (an arm of uniros arm add)")
    p.add_argument("--episodes", type=int, help="episodes to run (default: until Ctrl-C)")
    p.add_argument("--transport", choices=["zenoh", "rclpy"],
                   help="ROS transport to the robot (default: rclpy when importable, else zenoh)")
    p.add_argument("--router", metavar="ENDPOINT", help="the Zenoh router to join (tcp/HOST:PORT; default: "
                   "$UNIROS_ZENOH_ROUTER, else tcp/127.0.0.1:7447)")
    p.set_defaults(func=_cmd_deploy)


def build_parser() -> argparse.ArgumentParser:
    """The ``uniros`` argument parser."""
    from uniros.algorithms import ALGORITHMS
    from uniros.evaluation import EVAL_SEED

    parser = argparse.ArgumentParser(prog="uniros", description="Robot RL on ROS 2 with a MuJoCo simulation node.")
    parser.add_argument("--log-level", default="WARNING", help="logging level (default: %(default)s)")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("list", help="list the registered env IDs")
    p.set_defaults(func=_cmd_list)

    def env_options(p: argparse.ArgumentParser) -> None:
        p.add_argument("--sim-mode", choices=["composed", "process", "existing"],
                       help="run the simulation node in this process (default), a child process, "
                       "or reach a running one")
        p.add_argument("--transport", choices=["inproc", "zenoh", "rclpy"],
                       help="ROS transport (rclpy: your ROS 2 install and its middleware)")

    def device_option(p: argparse.ArgumentParser, what: str) -> None:
        p.add_argument("--device", metavar="{auto,cpu,cuda,cuda:N}",
                       help=f"torch device to {what} (default: the config's, else auto: the GPU for policies that "
                       "see camera images when CUDA is present, the CPU for MLPs; docs/training.md)")

    p = sub.add_parser("train", help="train an agent and evaluate it")
    p.add_argument("env_id", nargs="?",
                   help="a registered env ID (RX200ReacherGoalSim-v0) or module:ID (my_pkg.my_module:MyEnv-v0)")
    p.add_argument("--config", help="training YAML (default: the one shipped for the env ID)")
    p.add_argument("--steps", type=int, help="override training_steps")
    p.add_argument("--demos", metavar="DATASET", help="a recorded dataset (uniros record) whose episodes go into the "
                                                      "replay buffer before learning (off-policy algorithms)")
    p.add_argument("--seed", type=int, help="override the seed")
    p.add_argument("--n-envs", type=int, help="override n_envs: envs trained on at once, in one batched vector env")
    p.add_argument("--pin-workers", action=argparse.BooleanOptionalAction, default=None,
                   help="override pin_workers: with n_envs > 1, each worker process of the vector env on a core of "
                        "its own (for a machine the run has to itself)")
    p.add_argument("--target", type=float, default=0.9, help="success rate that counts as solved")
    p.add_argument("--eval-episodes", type=int, default=50,
                   help="episodes of the final evaluation (the ones `uniros eval` plays; 0: none)")
    p.add_argument("--output", default="runs", help="parent of the run directories (default: %(default)s)")
    p.add_argument("--name", help="run directory name (default: <env id>_<algo>_<timestamp>); never overwritten")
    p.add_argument("--init-from", metavar="MODEL",
                   help="start from a trained model's weights (a .zip or a run directory: its best model), "
                        "with this config's hyperparameters, a fresh replay buffer and step 0: fine-tune a "
                        "policy in a randomised world (docs/training.md)")
    p.add_argument("--init-buffer", action="store_true",
                   help="with --init-from RUN_DIR: start with that run's replay buffer too (its newest checkpoint's) "
                        "instead of an empty one, so the fine-tune keeps learning from the old worlds beside the "
                        "new ones (docs/sim_to_real.md)")
    p.add_argument("--resume", metavar="RUN_DIR",
                   help="continue a run from its newest usable checkpoint (from step 0 when it has none)")
    p.add_argument("--no-video", action="store_true", help="do not record best_model.mp4 (real-time speed)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    device_option(p, "train on")
    env_options(p)
    p.set_defaults(func=_cmd_train)

    p = sub.add_parser("eval", help="evaluate a saved model")
    p.add_argument("env_id", nargs="?", help="a registered env ID or module:ID (default: the run's, from its run.json)")
    p.add_argument("model", nargs="?", help="a model .zip (uniros' or rl-zoo3's) or a run directory (its best model)")
    p.add_argument("--env", help="evaluate on this env ID instead (equal spaces, e.g. RX200ReacherGoalReal-v0 for a "
                   "model trained on RX200ReacherGoalSim-v0)")
    p.add_argument("--algo", help=f"one of {', '.join(ALGORITHMS)} (default: read from the model file)")
    p.add_argument("--episodes", type=int, default=50)
    p.add_argument("--seed", type=int, default=EVAL_SEED,
                   help="episode i is reset with seed + i (default: %(default)s, the episodes every uniros "
                   "evaluation plays)")
    device_option(p, "run the model on")
    env_options(p)
    p.set_defaults(func=_cmd_eval)

    p = sub.add_parser("doctor", help="what this machine offers: GL backend, GPU, torch device, rclpy, RMW")
    p.set_defaults(func=_cmd_doctor)

    p = sub.add_parser("sim", help="run the simulation node (same options as uniros-sim)", add_help=False)
    p.add_argument("sim_args", nargs=argparse.REMAINDER)
    p.set_defaults(func=_cmd_sim)

    p = sub.add_parser("new", help="create a robot env + task env pair from the templates")
    p.add_argument("name", help="robot name in CamelCase, e.g. MyArm")
    p.add_argument("--directory", default=".", help="where to create the package (default: %(default)s)")
    p.add_argument("--goal", action="store_true", help="goal-conditioned (HER-ready) envs")
    p.add_argument("--style", choices=["multiros", "frobs"], default="multiros",
                   help="template style: MultiROS (MyRobotEnv/MyTaskEnv) or FRobs_RL (CustomRobotEnv/CustomTaskEnv)")
    p.set_defaults(func=_cmd_new)
    _arm_parser(sub)
    _deploy_parsers(sub)
    from uniros.recording import add_record_parser
    from uniros.sysid import add_sysid_parser
    from uniros.teleop import add_teleop_parser

    add_sysid_parser(sub)
    add_teleop_parser(sub)
    add_record_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``uniros`` console script."""
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    args, extra = parser.parse_known_args(argv)
    if args.command == "sim":
        # Everything after `sim` belongs to uniros-sim's own parser (--help included).
        args.sim_args = argv[argv.index("sim") + 1:]
    elif extra:
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    logging.basicConfig(level=args.log_level.upper(), format="[%(levelname)s] [%(name)s]: %(message)s")
    from multiros.envs.errors import EnvError
    from multiros.sim.client import SimulationNodeError
    from uniros.errors import TrainingError
    from uniros.interrupts import sigterm_as_interrupt

    try:
        with sigterm_as_interrupt():
            return int(args.func(args))
    except BrokenPipeError:
        # The reader went away (`uniros doctor | head`): quietly, as other command-line tools do.
        # Python's own advice: point stdout at devnull so the flush at exit does not raise again.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except KeyboardInterrupt as exc:
        print(f"\nuniros {args.command}: interrupted", file=sys.stderr)
        return 128 + int(getattr(exc, "signum", 2))
    except (TrainingError, ValueError, LookupError, FileNotFoundError, EnvError, SimulationNodeError) as exc:
        # A user's mistake or a missing robot/node: one or two lines, no traceback.
        line = excerpt(_one_message(exc), _MAX_ERROR, count_rest=True)
        print(f"uniros {args.command}: error: {line}", file=sys.stderr)
        return 2


_MAX_ERROR = 2000  # characters of an error line: a message may quote something hostile a file or the wire held


def _one_message(exc: BaseException) -> str:
    """The exception's message (LookupError's KeyError quotes dropped); its type for a real robot's error."""
    from multiros.envs.errors import EnvError

    text = str(exc.args[0]) if isinstance(exc, KeyError) and exc.args else str(exc)
    if isinstance(exc, EnvError) and not isinstance(exc, ValueError):
        text = f"{type(exc).__name__}: {text}"
    from multiros.envs.real.errors import RobotConnectionError

    if isinstance(exc, RobotConnectionError):
        text += ("\n  (a Real env drives a robot: start its driver, or `uniros-fake-robot` as a stand-in; "
                 "see docs/real_robots.md)")
    return text


if __name__ == "__main__":
    sys.exit(main())
