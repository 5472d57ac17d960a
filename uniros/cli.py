"""The ``uniros`` command: ``train``, ``eval``, ``list``, ``sim`` and ``new``.

Each subcommand is a small function taking parsed arguments and returning an exit code.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from collections.abc import Sequence
from pathlib import Path


def _cmd_list(args: argparse.Namespace) -> int:
    import rl_environments

    for env_id in rl_environments.ENV_IDS:
        kind = "goal" if env_id in rl_environments.GOAL_ENV_IDS else "plain"
        print(f"{env_id:32s} {kind}  {rl_environments.ENV_SPECS[env_id]}")
    return 0


def _env_overrides(args: argparse.Namespace) -> dict[str, object]:
    overrides: dict[str, object] = {}
    if args.sim_mode:
        overrides["sim_mode"] = args.sim_mode
    if args.transport:
        overrides["transport"] = args.transport
    return overrides


def _cmd_train(args: argparse.Namespace) -> int:
    import uniros
    from uniros.training import default_config_for, evaluate, load_training_config, train

    config = load_training_config(args.config) if args.config else default_config_for(args.env_id)
    if args.steps is not None:
        config.training_steps = args.steps
    if args.seed is not None:
        config.seed = args.seed
    config.env_kwargs.update(_env_overrides(args))
    output = Path(args.output)
    output.mkdir(parents=True, exist_ok=True)
    model_path = output / f"{args.env_id}_{config.algorithm}.zip"
    print(f"training {config.algorithm.upper()}{' + HER' if config.use_her else ''} on {args.env_id} "
          f"for {config.training_steps} steps (config: {config.source})", flush=True)

    def report(steps: int, seconds: float, rate: float) -> None:
        print(f"  steps {steps:6d}  train time {seconds:7.1f} s  eval success {rate:.2f}", flush=True)

    result = train(args.env_id, config, target=args.target, on_eval=report, save_path=model_path)
    # What `uniros eval` needs to rebuild the same env (e.g. ee_action_type changes the action space).
    model_path.with_suffix(".env.json").write_text(
        json.dumps({"env_id": args.env_id, "algorithm": config.algorithm, "env_kwargs": config.env_kwargs}, indent=2)
    )
    print(f"trained {result.total_steps} steps in {result.train_seconds:.1f} s; model saved to {model_path}")
    if result.steps_to_success is not None:
        print(f"first eval success >= {args.target}: {result.steps_to_success} steps, "
              f"{result.seconds_to_success:.1f} s of training")
    else:
        print(f"eval success never reached {args.target}")
    env = uniros.make(args.env_id, **config.env_kwargs)
    try:
        stats = evaluate(result.model, env, args.eval_episodes, seed=10_000_000 + (config.seed or 0),
                         normalizer=result.normalizer)
    finally:
        env.close()
    print(f"final evaluation over {args.eval_episodes} episodes: success rate {stats['success_rate']:.2f}, "
          f"mean return {stats['mean_return']:.2f}, mean length {stats['mean_length']:.1f}")
    return 0


def _cmd_eval(args: argparse.Namespace) -> int:
    import stable_baselines3 as sb3

    import uniros
    from uniros.training import evaluate

    saved: dict = {}
    meta = Path(args.model).with_suffix(".env.json")
    if meta.is_file():
        saved = json.loads(meta.read_text())
    algo = args.algo or saved.get("algorithm") or Path(args.model).stem.rsplit("_", 1)[-1]
    classes = {"sac": sb3.SAC, "td3": sb3.TD3, "ddpg": sb3.DDPG, "ppo": sb3.PPO, "a2c": sb3.A2C, "dqn": sb3.DQN}
    if algo not in classes:
        print(f"cannot tell the algorithm of {args.model!r}; pass --algo {{{','.join(classes)}}}", file=sys.stderr)
        return 2
    env = uniros.make(args.env_id, **{**saved.get("env_kwargs", {}), **_env_overrides(args)})
    try:
        normalizer = None
        stats_file = Path(args.model).with_suffix(".vecnormalize.pkl")
        if stats_file.is_file():
            from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

            normalizer = VecNormalize.load(str(stats_file), DummyVecEnv([lambda: env]))
            normalizer.training = False
        # HER models need an env to rebuild their replay buffer, even for prediction.
        model = classes[algo].load(args.model, env=normalizer if normalizer is not None else env, device="cpu")
        stats = evaluate(model, env, args.episodes, seed=args.seed, normalizer=normalizer)
    finally:
        env.close()
    print(f"{args.env_id}: success rate {stats['success_rate']:.2f} over {args.episodes} episodes, "
          f"mean return {stats['mean_return']:.2f}, mean length {stats['mean_length']:.1f}")
    return 0


def _cmd_sim(args: argparse.Namespace) -> int:
    from multiros.sim.launch import main as sim_main

    return sim_main(args.sim_args)


def _cmd_new(args: argparse.Namespace) -> int:
    from uniros.templates_cli import create_from_templates

    created = create_from_templates(args.name, Path(args.directory), goal=args.goal, style=args.style)
    for path in created:
        print(f"created {path}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The ``uniros`` argument parser."""
    parser = argparse.ArgumentParser(prog="uniros", description="Robot RL on ROS 2 with a MuJoCo simulation node.")
    parser.add_argument("--log-level", default="WARNING", help="logging level (default: %(default)s)")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("list", help="list the registered env IDs")
    p.set_defaults(func=_cmd_list)

    def env_options(p: argparse.ArgumentParser) -> None:
        p.add_argument("--sim-mode", choices=["composed", "process", "existing"],
                       help="run the simulation node in this process (default), a child process, "
                       "or reach a running one")
        p.add_argument("--transport", choices=["inproc", "zenoh"], help="ROS transport")

    p = sub.add_parser("train", help="train an agent and evaluate it")
    p.add_argument("env_id", help="a registered env ID, e.g. RX200ReacherGoalSim-v0")
    p.add_argument("--config", help="training YAML (default: the one shipped for the env ID)")
    p.add_argument("--steps", type=int, help="override training_steps")
    p.add_argument("--seed", type=int, help="override the seed")
    p.add_argument("--target", type=float, default=0.9, help="success rate that counts as solved")
    p.add_argument("--eval-episodes", type=int, default=50, help="episodes of the final evaluation")
    p.add_argument("--output", default="runs", help="directory for the trained model (default: %(default)s)")
    env_options(p)
    p.set_defaults(func=_cmd_train)

    p = sub.add_parser("eval", help="evaluate a saved model")
    p.add_argument("env_id")
    p.add_argument("model", help="a model .zip saved by `uniros train`")
    p.add_argument("--algo", help="sac, td3, ddpg, ppo, a2c or dqn (default: from the file name)")
    p.add_argument("--episodes", type=int, default=50)
    p.add_argument("--seed", type=int, default=0)
    env_options(p)
    p.set_defaults(func=_cmd_eval)

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
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``uniros`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=args.log_level.upper(), format="[%(levelname)s] [%(name)s]: %(message)s")
    try:
        return int(args.func(args))
    except KeyboardInterrupt:
        return 130
    except (ValueError, LookupError, FileNotFoundError) as exc:
        print(f"uniros {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
