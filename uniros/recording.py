"""``uniros record ID --policy scripted|teleop|RUN --episodes N --output DIR [--images]``: episodes written as
a LeRobot dataset.

Plays ``N`` episodes of the env ``ID`` (episode ``k`` reset with seed ``S + k``) with its task's scripted
policy or a trained run (loaded as ``uniros eval`` loads it: the run's env kwargs, its spaces checked, its
normalisation statistics) and writes every step as a frame of a LeRobot v3.0 dataset
(:mod:`uniros.lerobot_dataset`)::

    observation.state            the state observation (a goal env's "observation", or the plain vector)
    observation.achieved_goal    a goal env's other keys, one feature each (observation.desired_goal, ...)
    observation.environment_state  those other vector keys concatenated in key order (a goal env:
                                 achieved_goal then desired_goal), as LeRobot's envs give them
                                 (uniros.lerobot_env): a LeRobot policy trained on the dataset takes
                                 what a LeRobot eval of the env passes it
    action                       the action taken, as the env took it
    next.reward, next.done       the step's reward and whether the episode ended there
    next.success                 the step's info["is_success"]
    observation.images.rgb       with --images: the camera's RGB frames, as the dataset's MP4 video

``--images`` makes the env with a camera (``rgb_plus_normal_obs=True``, ``--image-size WxH``) unless
it already has one, and writes its frames as video (:mod:`uniros.lerobot_video`: h264 by default).
Each episode carries its task string (the task's kind, e.g. "push the cube to the goal"), its success
(the last step's ``is_success``) and the observation after its last step (for replay buffers:
:mod:`uniros.demonstrations_io`). ``info.json`` names the env ID and its spaces under ``"uniros"``.
Errors are one line, exit code 2 (docs/datasets.md).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["ENVIRONMENT_STATE", "STATE_KEYS", "RecordError", "add_record_parser", "cmd_record", "dataset_features",
           "environment_state", "environment_state_keys", "frame_of", "image_env_kwargs", "is_vector_space", "main",
           "record"]

#: The task strings of the arm tasks' kinds (the episode's "task" in the dataset).
TASK_TEXT = {
    "push": "push the cube to the goal",
    "pnp": "pick up the cube and place it at the goal",
    "reach": "move the end effector to the goal",
    "slide": "slide the puck to the goal",
    "frobs_reach": "move the end effector to the goal",
}


class RecordError(ValueError):
    """``uniros record`` cannot go on: the message names what and the fix."""


def _feature(space: Any) -> dict[str, Any]:
    shape = [int(n) for n in space.shape] or [1]
    dtype = "uint8" if space.dtype == np.uint8 else "float32"
    return {"dtype": dtype, "shape": shape, "names": None}


def _is_image(space: Any) -> bool:
    return len(getattr(space, "shape", ())) == 3 and getattr(space, "dtype", None) == np.uint8


#: The keys of a Dict observation that hold its state vector (the first, in sorted order, that is a vector).
STATE_KEYS = ("observation", "state")
ENVIRONMENT_STATE = "observation.environment_state"


def is_vector_space(space: Any) -> bool:
    """Whether ``space`` is a one-dimensional Box: a state vector, not an image."""
    from gymnasium import spaces

    return isinstance(space, spaces.Box) and len(space.shape) == 1


def environment_state_keys(observation_space: Any) -> list[str]:
    """The vector keys of a Dict observation besides its state vector, sorted: what LeRobot's
    ``observation.environment_state`` holds, concatenated in this order (a goal env: ``achieved_goal``,
    ``desired_goal``). Empty for a Box observation."""
    from gymnasium import spaces

    if not isinstance(observation_space, spaces.Dict):
        return []
    keys = sorted(observation_space.spaces)
    vectors = [k for k in keys if is_vector_space(observation_space.spaces[k])]
    state = next((k for k in vectors if k in STATE_KEYS), None)
    return [k for k in vectors if k != state]


def environment_state(obs: Any, keys: Sequence[str]) -> np.ndarray:
    """``obs``'s :func:`environment_state_keys` ``keys`` concatenated (float32)."""
    return np.concatenate([np.asarray(obs[k], dtype=np.float32).ravel() for k in keys])


def dataset_features(observation_space: Any, action_space: Any, *,
                     images: bool = False) -> tuple[dict[str, dict[str, Any]], dict[str, str]]:
    """The dataset's features for an env's spaces, and ``{feature: observation key}`` ("" for a plain Box).

    A goal env's ``observation`` is ``observation.state``, its other keys ``observation.<key>``. Camera
    images (uint8 H x W x 3 keys) are ``observation.images.<key>`` of dtype ``video`` with ``images``, and
    left out without.
    """
    from gymnasium import spaces

    feats: dict[str, dict[str, Any]] = {}
    keys: dict[str, str] = {}
    if isinstance(observation_space, spaces.Dict):
        for key, sub in observation_space.spaces.items():
            if _is_image(sub):
                if images:
                    name = f"observation.images.{key}"
                    feats[name] = {"dtype": "video", "shape": [int(n) for n in sub.shape or ()],
                                   "names": ["height", "width", "channels"]}
                    keys[name] = key
                continue
            if not isinstance(sub, spaces.Box):
                raise RecordError(f"observation key {key!r} is a {type(sub).__name__}: only Box observations record")
            name = "observation.state" if key in ("observation", "state") else f"observation.{key}"
            feats[name], keys[name] = _feature(sub), key
    elif isinstance(observation_space, spaces.Box) and not _is_image(observation_space):
        feats["observation.state"], keys["observation.state"] = _feature(observation_space), ""
    else:
        raise RecordError(f"a {type(observation_space).__name__} observation space does not record as joint state")
    if "observation.state" not in feats:
        raise RecordError("the env's observations have no state vector (a camera-only env): record one with "
                          "rgb_plus_normal_obs")
    if not isinstance(action_space, spaces.Box):
        raise RecordError(f"a {type(action_space).__name__} action space does not record: uniros records Box actions")
    feats["action"] = {**_feature(action_space), "dtype": "float32"}
    for name, dtype in (("next.reward", "float32"), ("next.done", "bool"), ("next.success", "bool")):
        feats[name] = {"dtype": dtype, "shape": [1], "names": None}
    return feats, keys


def frame_of(obs: Any, keys: dict[str, str]) -> dict[str, Any]:
    """An observation's features (``keys`` from :func:`dataset_features`)."""
    return {name: (obs[key] if key else obs) for name, key in keys.items()}


def task_text(env: Any, env_id: str) -> str:
    """The episode's task string: the arm task's name (its row of the task table) in words, else the env ID
    (an env of your own)."""
    name = getattr(getattr(env.unwrapped, "task", None), "NAME", None)
    return TASK_TEXT.get(str(name), f"{env_id}")


def _fps(env: Any) -> int:
    fps = env.metadata.get("render_fps") if isinstance(getattr(env, "metadata", None), dict) else None
    if not fps:
        dt = getattr(env.unwrapped, "dt", None)
        fps = round(1.0 / dt) if dt else 25
    return max(1, int(round(float(fps))))


def record(env: Any, policy: Callable[[Any], Any], episodes: int, output: Path, *, env_id: str, seed: int = 0,
           progress: bool = True, reset: Callable[[], None] | None = None, images: bool = False,
           video: Any = None) -> dict[str, Any]:
    """Play ``episodes`` episodes of ``env`` with ``policy`` and write them to the new dataset ``output``;
    ``images``: its camera images too, as video (``video``: a :class:`uniros.lerobot_video.VideoSettings`).

    Returns ``{"episodes", "frames", "success_rate", "path"}``. On any error (or Ctrl-C) nothing is left
    at ``output``.
    """
    from tqdm import tqdm

    from uniros.lerobot_dataset import DatasetWriter

    if episodes <= 0:
        raise RecordError(f"--episodes must be at least 1, got {episodes}")
    feats, keys = dataset_features(env.observation_space, env.action_space, images=images)
    if images and not any(ft["dtype"] == "video" for ft in feats.values()):
        raise RecordError(f"{env_id}'s observations have no camera image (uint8 H x W x 3): make it with "
                          "rgb_plus_normal_obs=True, or record without --images")
    env_keys = environment_state_keys(env.observation_space)
    if env_keys:  # derived: readers of uniros' own layout (demonstrations_io) use the keys above
        size = sum(int(np.prod(env.observation_space.spaces[k].shape)) for k in env_keys)
        feats[ENVIRONMENT_STATE] = {"dtype": "float32", "shape": [size], "names": None}
    arm = getattr(getattr(env.unwrapped, "task", None), "arm", None)
    robot = getattr(arm, "name", None) or env_id.split("-")[0]
    extra = {"uniros": {"env_id": env_id, "observation_keys": keys, "environment_state": env_keys,
                        "action_shape": list(env.action_space.shape), "seed": seed}}
    writer = DatasetWriter(output, _fps(env), feats, robot_type=str(robot), extra_info=extra, video=video)
    task = task_text(env, env_id)
    state_keys = {k: v for k, v in keys.items() if feats[k]["dtype"] != "video"}  # the final obs: no image
    successes = frames = 0
    bar = tqdm(total=episodes, unit="episode", desc=f"recording {env_id}", disable=not progress)
    try:
        for k in range(episodes):
            obs, info = env.reset(seed=seed + k)
            if reset is not None:
                reset()
            done = False
            while not done:
                action = np.asarray(policy(obs), dtype=np.float32)
                next_obs, reward, terminated, truncated, info = env.step(action)
                done = bool(terminated or truncated)
                frame = frame_of(obs, keys)
                if env_keys:
                    frame[ENVIRONMENT_STATE] = environment_state(obs, env_keys)
                frame["action"] = action
                frame["next.reward"] = reward
                frame["next.done"] = done
                frame["next.success"] = bool(info.get("is_success", False))
                writer.add_frame(frame)
                obs = next_obs
                frames += 1
            success = bool(info.get("is_success", False))
            successes += int(success)
            writer.save_episode(task, success=success, final=frame_of(obs, state_keys))
            bar.update(1)
            bar.set_postfix(success=f"{successes}/{k + 1}")
        path = writer.finalize()
    except BaseException:
        writer.abort()
        raise
    finally:
        bar.close()
    return {"episodes": episodes, "frames": frames, "success_rate": successes / episodes, "path": path}


# -- policies ----------------------------------------------------------------------------------------
def _scripted(env: Any) -> tuple[Callable[[Any], Any], Callable[[], None] | None]:
    task = getattr(env.unwrapped, "task", None)
    if task is None or not hasattr(task, "scripted_policy"):
        raise RecordError(f"{type(env.unwrapped).__name__} has no task with a scripted policy: record a trained run")
    try:
        policy = task.scripted_policy()
    except ValueError as exc:
        raise RecordError(f"no scripted policy: {str(exc).splitlines()[0]}") from None
    return policy, getattr(policy, "reset", None)


def _trained(model_path: Path, env: Any, env_id: str, device: str | None) -> Callable[[Any], Any]:
    from uniros.model_files import load_for_eval
    from uniros.model_spaces import SpaceMismatchError, check_model_spaces

    try:
        check_model_spaces(model_path, env, env_id)
    except SpaceMismatchError as exc:
        raise RecordError(str(exc).splitlines()[0]) from None
    model, normalizer = load_for_eval(model_path, env, device=device)

    def act(obs: Any) -> Any:
        return model.predict(obs if normalizer is None else normalizer.normalize_obs(obs), deterministic=True)[0]

    return act


# -- the command -------------------------------------------------------------------------------------
def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("env_id", metavar="ID", help="the env to record (a registered ID, or module:ID)")
    p.add_argument("--policy", required=True, metavar="scripted|teleop|RUN",
                   help="'scripted' (the task's scripted policy), 'teleop' (a person, through --joy or --twist: "
                        "uniros teleop) or a trained run (a run folder or model .zip)")
    p.add_argument("--joy", metavar="TOPIC", help="teleop: sensor_msgs/Joy topic")
    p.add_argument("--twist", metavar="TOPIC", help="teleop: geometry_msgs/Twist topic")
    p.add_argument("--joy-map", default="", metavar="MAP", help="teleop: x=1,y=0,z=4,close=0,open=1 (the default)")
    p.add_argument("--twist-scale", type=float, default=0.5, help="teleop: speed meaning a full step (%(default)s)")
    p.add_argument("--transport", choices=["zenoh", "rclpy"], help="teleop: ROS transport of the input topic")
    p.add_argument("--router", metavar="ENDPOINT", help="teleop: the Zenoh router to join (tcp/HOST:PORT)")
    p.add_argument("--episodes", type=int, required=True, metavar="N", help="episodes to record")
    p.add_argument("--output", required=True, metavar="DIR", help="the new dataset's folder (must not exist)")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="episode k is reset with seed S + k (default 0)")
    p.add_argument("--images", action="store_true",
                   help="also record the camera's RGB images, as the dataset's MP4 video (the env is made with "
                        "rgb_plus_normal_obs=True unless it has a camera already)")
    p.add_argument("--image-size", metavar="WxH", help="with --images: the camera's width x height (default 84x84; "
                                                         "even numbers)")
    p.add_argument("--video-codec", default="h264", metavar="CODEC",
                   help="with --images: h264 (default), hevc or libsvtav1 (LeRobot's default: smaller, slower)")
    p.add_argument("--crf", type=int, default=23, help="with --images: the video's quality, 0 best .. 51 (%(default)s)")
    p.add_argument("--device", default=None, help="torch device of a trained run (default: auto)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def image_env_kwargs(args: argparse.Namespace, kwargs: dict[str, Any]) -> dict[str, Any]:
    """The env keywords ``--images`` and ``--image-size`` add to ``kwargs`` (a run's env kwargs): a camera
    observation (``rgb_plus_normal_obs=True``) unless ``kwargs`` already asks for one, and its size."""
    from rl_environments.camera_obs import MODES

    if not args.images:
        if args.image_size:
            raise RecordError("--image-size is the size of the recorded images: give --images too")
        return {}
    extra: dict[str, Any] = {}
    if not any(kwargs.get(mode) for mode in MODES):
        extra["rgb_plus_normal_obs"] = True
    if args.image_size:
        width, sep, height = str(args.image_size).lower().partition("x")
        if not (sep and width.isdigit() and height.isdigit()):
            raise RecordError(f"--image-size {args.image_size!r}: give WIDTHxHEIGHT, e.g. 64x48")
        extra["image_width"], extra["image_height"] = int(width), int(height)
    return extra


def _video_settings(args: argparse.Namespace) -> Any:
    from uniros.lerobot_video import VideoFormatError, VideoSettings

    try:
        return VideoSettings(codec=args.video_codec, crf=args.crf)
    except VideoFormatError as exc:
        raise RecordError(f"--video-codec/--crf: {exc}") from None


def add_record_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``record`` to ``uniros``' subcommands (``args.func`` is :func:`cmd_record`)."""
    p = subparsers.add_parser("record", help="record episodes (scripted or a trained run) as a LeRobot dataset "
                                             "(docs/datasets.md)", description=__doc__.split("\n\n")[0])
    _add_arguments(p)
    p.set_defaults(func=cmd_record)
    return p


def cmd_record(args: argparse.Namespace) -> int:
    """Run ``uniros record``; errors are raised (``main`` and the CLI print them in one line)."""
    from uniros.run_envs import check_env_id, make_env

    output = Path(args.output)
    if output.exists():
        raise RecordError(f"{output} exists: record into a new folder")
    video = _video_settings(args)
    env_id = check_env_id(args.env_id)
    kwargs: dict[str, Any] = {}
    model_path = None
    if args.policy == "teleop":
        return _record_teleop(args, env_id, output, video)
    if args.joy or args.twist:
        raise RecordError("--joy and --twist are teleop's inputs: give --policy teleop")
    if args.policy != "scripted":
        from uniros.model_files import resolve_model_path, saved_env_kwargs

        model_path = resolve_model_path(args.policy)
        kwargs = saved_env_kwargs(model_path, env_id) or {}
    kwargs = {**kwargs, **image_env_kwargs(args, kwargs)}
    env = make_env(env_id, **kwargs)
    try:
        if model_path is None:
            policy, reset = _scripted(env)
        else:
            policy, reset = _trained(model_path, env, env_id, args.device), None
        result = record(env, policy, args.episodes, output, env_id=env_id, seed=args.seed,
                        progress=not args.no_progress, reset=reset, images=args.images, video=video)
    finally:
        env.close()
    print(f"{result['path']}: {result['episodes']} episodes, {result['frames']} frames of {env_id}, "
          f"success {result['success_rate']:.2f} (LeRobot v3.0 dataset{', images as video' if args.images else ''})")
    return 0


def _record_teleop(args: argparse.Namespace, env_id: str, output: Path, video: Any) -> int:
    """``--policy teleop``: a person drives (:mod:`uniros.teleop`), the env at its control rate, every step written."""
    import threading
    import time

    from multiros.ros import Context
    from multiros.ros.executors import SingleThreadedExecutor
    from multiros.ros.processes import discovery_environment
    from multiros.ros.transport import wire_transport
    from uniros.run_envs import make_env
    from uniros.teleop import TeleopInput, TeleopPolicy, subscribe, teleop_env_kwargs

    if not (args.joy or args.twist) or (args.joy and args.twist):
        raise RecordError("--policy teleop reads one input: give --joy TOPIC or --twist TOPIC")
    transport = wire_transport(args.transport)
    options: dict[str, Any] = {"router": args.router} if args.router and transport == "zenoh" else {}
    context = Context(transport=transport, env=discovery_environment(), **options).init()
    env = None
    try:
        extra: dict[str, Any] = {"context": context} if "Real" in env_id else {}
        kwargs = teleop_env_kwargs(env_id)
        env = make_env(env_id, **kwargs, **image_env_kwargs(args, kwargs), **extra)
        source = TeleopInput()
        person = TeleopPolicy(source, env.action_space)
        node = subscribe(context, source, args)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        threading.Thread(target=executor.spin, name="uniros-record-teleop", daemon=True).start()
        core: Any = env.unwrapped
        period = 0.0 if core.ON_ROBOT else float(core.connection.control_period)
        clock = {"next": time.monotonic()}

        def paced(obs: Any) -> Any:  # a person drives at the robot's pace, not the simulation's
            clock["next"] = max(clock["next"] + period, time.monotonic())
            time.sleep(max(0.0, clock["next"] - time.monotonic()))
            return person(obs)

        result = record(env, paced, args.episodes, output, env_id=env_id, seed=args.seed,
                        progress=not args.no_progress, reset=None, images=args.images, video=video)
    finally:
        if env is not None:
            env.close()
        context.try_shutdown()
    print(f"{result['path']}: {result['episodes']} episodes, {result['frames']} frames of {env_id} driven by hand, "
          f"success {result['success_rate']:.2f} (LeRobot v3.0 dataset)")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``uniros record`` on its own: ``main(["ID", "--policy", "scripted", ...])``; errors: one line, return 2."""
    from uniros.errors import TrainingError
    from uniros.lerobot_dataset import DatasetFormatError

    parser = argparse.ArgumentParser(prog="uniros record", description=__doc__.split("\n\n")[0])
    _add_arguments(parser)
    args = parser.parse_args(list(sys.argv[1:] if argv is None else argv))
    try:
        return cmd_record(args)
    except (RecordError, DatasetFormatError, TrainingError, ValueError, OSError) as exc:
        text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        print(f"uniros record: error: {text[:2000]}", file=sys.stderr)
        return 2
