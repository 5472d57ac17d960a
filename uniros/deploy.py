"""``uniros deploy``: an exported policy (``uniros export``) driving a robot through its Real env.

The policy runs in onnxruntime (:class:`~uniros.onnx_policy.OnnxPolicy`); torch and Stable-Baselines3 are
never imported, so a robot's machine needs only ``pip install 'uniros[deploy]'``. The robot is driven by the
Real twin of the ID the policy was trained on (``RX200ReacherGoalSim-v0`` -> ``RX200ReacherGoalReal-v0``),
made as ``uniros eval RUN --env <Real ID>`` makes it: its safety rules, its control loop (the period it
keeps), its reset and its staleness watchdog apply unchanged, and the task options of the run (``env_kwargs``
of the policy's record) carry over, the simulation's knobs left out.

Each step times the policy's inference; the end prints the inference time's p50/p99 and the control period
kept (p50/p99 of the time between observations), and each episode's success as it ends. Ctrl-C (or SIGTERM)
stops cleanly: the arm is commanded to hold the position measured at that moment (through the safety
rules), the env is closed, one line is printed and the exit code is 0.
"""

from __future__ import annotations

import contextlib
import gc
import os
import signal
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from uniros.errors import TrainingError
from uniros.onnx_policy import OnnxPolicy
from uniros.policy_metadata import PolicyFileError, PolicyMetadata, file_sha256

#: The GIL switch interval while the policy drives the robot (s).
SWITCH_INTERVAL = 2e-4
#: The files ``uniros export RUN`` writes, in the order ``uniros deploy RUN`` looks for them.
RUN_POLICIES = ("best_model.onnx", "final_model.onnx")


class DeployError(TrainingError, ValueError):
    """What was asked cannot be deployed (no policy, an ID that does not fit, spaces that differ)."""


# -- what to deploy -----------------------------------------------------------------------------------
def policy_file(target: str | os.PathLike[str]) -> Path:
    """The ONNX file of ``target``: the file itself, or the exported policy of a run directory.

    Raises:
        DeployError: nothing there, a run without an exported policy, or one older than its model.
    """
    path = Path(target)
    if path.is_dir():
        found = next((path / name for name in RUN_POLICIES if (path / name).is_file()), None)
        if found is None:
            raise DeployError(f"{path} holds no exported policy ({' or '.join(RUN_POLICIES)}): run `uniros export "
                              f"{path}` first (on a machine with the train extra)")
        return found
    if not path.exists():
        raise DeployError(f"{str(path)!r}: no such file or run directory")
    return path


def check_not_stale(path: Path, metadata: PolicyMetadata) -> None:
    """A run's exported policy must come from the model beside it (a resumed run replaces its models).

    Raises:
        DeployError: ``<model>.zip`` beside ``path`` is not the model ``path`` was exported from.
    """
    model = path.with_suffix(".zip")
    if not model.is_file() or not metadata.source_sha256:
        return
    if file_sha256(model) != metadata.source_sha256:
        raise DeployError(f"{path} was exported from another {model.name} than the one beside it (the run went on "
                          f"since): export it again, `uniros export {path.parent}`")


def real_env_id(metadata: PolicyMetadata, typed: str | None) -> str:
    """The Real ID to deploy on: ``typed`` (the policy's ID's Real twin, or its own ID if that is a Real one),
    else that twin.

    Raises:
        DeployError: the policy's ID has no Real twin, or ``typed`` is another env.
    """
    import rl_environments

    trained = metadata.env_id.rpartition(":")[2]
    twin = trained if trained in rl_environments.REAL_ENV_SPECS else rl_environments.SIM_TO_REAL.get(trained)
    if typed is not None:
        bare = typed.rpartition(":")[2]
        if bare != twin:
            wanted = f"its Real twin {twin}" if twin else "a Real ID (it has none)"
            raise DeployError(f"the policy was trained on {metadata.env_id}, not for {typed}: deploy it on {wanted}")
    if twin is None:
        raise DeployError(f"the policy was trained on {metadata.env_id}, which has no Real twin (`uniros list` shows "
                          "the real IDs)")
    return twin


def register_arm_for(metadata: PolicyMetadata, where: Path, arm: str | None, typed: bool,
                     note: Callable[[str], None]) -> None:
    """Register the arm file the policy's ID needs, when this process has not: ``arm`` (``--arm``), else the
    one the record names (relative to the policy's folder), only when the ID was typed (``--env``): an arm
    file's xacro runs code, and a policy file comes from anywhere (docs/trust.md).

    Raises:
        DeployError: the ID is not registered and no arm file may be read for it.
    """
    import gymnasium as gym

    import rl_environments  # noqa: F401 - registers the shipped IDs
    from rl_environments.arm_file import ArmFileError
    from rl_environments.arm_registry import register_arm

    trained = metadata.env_id.rpartition(":")[2]
    twin = rl_environments.SIM_TO_REAL.get(trained, trained)
    if arm is not None:
        try:
            register_arm(Path(arm))
        except (ArmFileError, OSError) as exc:
            raise DeployError(f"--arm {arm}: {exc}") from None
        note(f"registered the arm file {arm}")
    if trained in gym.registry or twin in gym.registry:
        return
    if metadata.arm_file is None:
        raise DeployError(f"{metadata.env_id} is not registered in this process: pass --arm FILE (its arm file)")
    path = Path(metadata.arm_file)
    path = path if path.is_absolute() else where.parent / path
    if not typed:
        raise DeployError(f"the policy's env {metadata.env_id} comes from the arm file {path} (its xacro may run "
                          f"code): pass --arm {path}, or type the ID with --env")
    if not path.is_file():
        raise DeployError(f"the policy's env {metadata.env_id} comes from the arm file {path}, which is gone: pass "
                          "--arm FILE")
    try:
        register_arm(path)
    except ArmFileError as exc:
        raise DeployError(f"the arm file {path}: {exc}") from None
    note(f"registered the arm file {path} the policy was trained with")


def real_env_kwargs(metadata: PolicyMetadata, transport: str | None) -> dict[str, Any]:
    """The run's task options for the Real twin: the simulation's knobs and its transport left out."""
    from multiros.envs.real.core import SIMULATION_KNOBS

    kwargs = {k: v for k, v in metadata.env_kwargs.items() if k not in SIMULATION_KNOBS and k != "transport"}
    if transport is not None:
        kwargs["transport"] = transport
    return kwargs


def check_spaces(policy: OnnxPolicy, env: Any, env_id: str) -> None:
    """The env's observation (keys and shapes) and action space (shape and bounds) are the policy's.

    Raises:
        DeployError: they differ (the message says where).
    """
    from gymnasium import spaces

    meta, obs_space, action = policy.metadata, env.observation_space, env.action_space
    keys = meta.keys
    if keys is None:
        shapes = {meta.inputs[0].name: getattr(obs_space, "shape", None)} if not isinstance(obs_space, spaces.Dict) \
            else None
    else:
        shapes = {k: s.shape for k, s in obs_space.spaces.items()} if isinstance(obs_space, spaces.Dict) else None
    wanted = {i.name: i.shape for i in meta.inputs}
    if shapes is None or (set(shapes) != set(wanted) if keys is not None else False) or any(
            tuple(shapes.get(k) or ()) != v for k, v in wanted.items()):
        raise DeployError(f"{env_id}'s observation space {obs_space} is not the policy's ({wanted})")
    if not isinstance(action, spaces.Box) or action.shape != meta.action_shape or not (
            np.allclose(action.low, meta.action_low, atol=1e-6) and np.allclose(action.high, meta.action_high,
                                                                                  atol=1e-6)):
        raise DeployError(f"{env_id}'s action space {action} is not the policy's (Box({list(meta.action_low)}, "
                          f"{list(meta.action_high)}))")


# -- running it ---------------------------------------------------------------------------------------
@dataclass
class DeployStats:
    """What a deployment measured: per-step inference and observation intervals (s), per-episode success."""

    inference: list[float] = field(default_factory=list)
    periods: list[float] = field(default_factory=list)
    successes: list[bool] = field(default_factory=list)
    target_period: float | None = None

    def summary(self) -> str:
        """One line: episodes and successes, inference p50/p99, the control period kept."""
        def ms(values: list[float], q: float) -> str:
            return f"{1000 * float(np.percentile(values, q)):.3f}" if values else "n/a"

        n = len(self.successes)
        target = f" (target {1000 * self.target_period:.1f} ms)" if self.target_period else ""
        return (f"{n} episode{'s' if n != 1 else ''}, success {sum(self.successes)}/{n}; inference p50 "
                f"{ms(self.inference, 50)} ms, p99 {ms(self.inference, 99)} ms over {len(self.inference)} steps; "
                f"control period p50 {ms(self.periods, 50)} ms, p99 {ms(self.periods, 99)} ms{target}")


@contextlib.contextmanager
def low_latency() -> Iterator[None]:
    """The interpreter set for a control loop: no cyclic garbage collection within an episode (it runs between
    them), and a short GIL switch interval, so that the thread of the step gets the GIL back soon after
    onnxruntime releases it while the transport's threads deliver messages (CPython's default is 5 ms)."""
    interval = sys.getswitchinterval()
    enabled = gc.isenabled()
    sys.setswitchinterval(SWITCH_INTERVAL)
    gc.disable()
    try:
        yield
    finally:
        sys.setswitchinterval(interval)
        if enabled:
            gc.enable()


def run_episodes(policy: OnnxPolicy, env: Any, episodes: int | None, stats: DeployStats,
                 say: Callable[[str], None]) -> None:
    """Run ``episodes`` episodes (``None``: until interrupted), recording into ``stats``."""
    with low_latency():
        _run_episodes(policy, env, episodes, stats, say)


def _run_episodes(policy: OnnxPolicy, env: Any, episodes: int | None, stats: DeployStats,
                  say: Callable[[str], None]) -> None:
    clock = time.perf_counter
    warm = False
    episode = 0
    while episodes is None or episode < episodes:
        gc.collect()
        obs, info = env.reset()
        if not warm:  # onnxruntime's first run allocates: not a step's figure
            policy.act(obs)
            warm = True
        episode += 1
        done, steps, total, last = False, 0, 0.0, None
        while not done:
            start = clock()
            action = policy.act(obs)
            stats.inference.append(clock() - start)
            obs, reward, terminated, truncated, info = env.step(action)
            now = time.monotonic()
            if last is not None:
                stats.periods.append(now - last)
            last = now
            steps += 1
            total += float(reward)
            done = bool(terminated or truncated)
        success = bool(info.get("is_success", False))
        stats.successes.append(success)
        say(f"episode {episode}: {'success' if success else 'failure'}, {steps} steps, return {total:.2f}")


def hold_position(env: Any) -> str:
    """Command the arm to hold the position measured now (through the safety rules); what happened."""
    core = env.unwrapped
    try:
        sample = core.connection.fresh_sample()
        index = {name: i for i, name in enumerate(sample.names)}
        measured = np.asarray([sample.position[index[j]] for j in core.arm_joints], dtype=np.float64)
        decision = core.send_joint_targets(measured)
    except Exception as exc:  # noqa: BLE001 - a stale or lost robot: nothing can be commanded
        return f"no hold command ({type(exc).__name__}: {str(exc)[:160]}); the robot holds its last command"
    if decision.refused:
        return f"the safety rules refused the hold ({decision.reason}); the robot holds its last command"
    return "the arm holds its measured position"


def deploy(target: str, *, env_id: str | None = None, arm: str | None = None, episodes: int | None = None,
           transport: str | None = None, router: str | None = None,
           say: Callable[[str], None] = print, note: Callable[[str], None] | None = None) -> int:
    """``uniros deploy``: load, check, make the Real env, run; the exit code (0, also after Ctrl-C).

    Raises:
        DeployError, PolicyFileError: bad input (the CLI prints one line and exits 2).
        EnvError and its kinds: the robot could not be reached or failed (likewise).
    """
    note = note or (lambda text: print(f"note: {text}", file=sys.stderr, flush=True))
    if episodes is not None and episodes < 1:
        raise DeployError(f"--episodes must be at least 1, got {episodes}")
    if router is not None:
        from multiros.ros.transport.zenoh.config import ROUTER_ENV

        os.environ[ROUTER_ENV] = router
    path = policy_file(target)
    policy = OnnxPolicy(path)
    if Path(target).is_dir():
        check_not_stale(path, policy.metadata)
    import rl_environments  # noqa: F401 - the IDs

    register_arm_for(policy.metadata, path, arm, env_id is not None, note)
    real_id = real_env_id(policy.metadata, env_id)
    stats = DeployStats()
    env = None
    try:
        from uniros.run_envs import make_env

        env = make_env(real_id, **real_env_kwargs(policy.metadata, transport))
        check_spaces(policy, env, real_id)
        stats.target_period = float(env.unwrapped.loop.period)
        say(f"deploying {path} ({policy.metadata.algorithm.upper()}, trained on {policy.metadata.env_id}) on "
            f"{real_id}: control period {1000 * stats.target_period:.1f} ms, "
            f"{'until Ctrl-C' if episodes is None else f'{episodes} episodes'} (Ctrl-C stops with the arm holding)")
        run_episodes(policy, env, episodes, stats, say)
    except KeyboardInterrupt as exc:
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)  # a second Ctrl-C must not cut the hold short
        try:
            held = hold_position(env) if env is not None else "no robot commanded yet"
            if env is not None:
                env.close()
                env = None
        finally:
            signal.signal(signal.SIGINT, previous)
        name = signal.Signals(int(getattr(exc, "signum", signal.SIGINT))).name
        say(f"stopped on {'Ctrl-C' if name == 'SIGINT' else name}: {held}; {stats.summary()}")
        return 0
    finally:
        if env is not None:
            env.close()
    say(stats.summary())
    return 0


__all__ = ["RUN_POLICIES", "DeployError", "DeployStats", "PolicyFileError", "check_spaces", "deploy", "hold_position",
           "policy_file", "real_env_id", "real_env_kwargs", "register_arm_for", "run_episodes"]
