"""``uniros arm check``: an arm file's IDs tried with the scripted policies, so that a file that
registers is a file that works.

An arm file can load, hold its chain and register twelve IDs and still be of no use: a gripper the
simulation cannot close on the cube, a scene the arm cannot reach, a start pose in the table. The
scripted policies (:mod:`rl_environments.manipulation_scripted`) read only the observation and act
through the arm's top-down IK, so they succeed on an arm whose file is right: reach goes to the goal,
push and pick-and-place grasp the cube and carry it. :func:`check_arm` runs them on a few fixed seeds
of the arm's goal-conditioned IDs (``ReacherGoal``, and ``PushGoal`` and ``PnPGoal`` with a gripper)
and reports each task's success; ``uniros arm add`` runs it on the file it drafted before writing it.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from multiros.excerpt import error_line
from rl_environments.arm_file import ArmFileError

__all__ = ["ArmCheck", "TaskCheck", "check_arm", "refusal", "CHECK_TASKS", "PASS_RATE"]

#: The tasks tried, the goal-conditioned ones (each env ID is ``<name><task>Sim-v0``).
CHECK_TASKS = ("ReacherGoal", "PushGoal", "PnPGoal")
#: The scripted success a task must reach on the seeds tried.
PASS_RATE = 0.6


@dataclass
class TaskCheck:
    """One task's scripted episodes: ``successes`` of ``episodes``, why the others ended."""

    env_id: str
    episodes: int = 0
    successes: int = 0
    failures: list[str] = field(default_factory=list)  # one reason per failed episode
    error: str = ""  # the env could not be made or stepped: one line

    @property
    def rate(self) -> float:
        return self.successes / self.episodes if self.episodes else 0.0

    @property
    def passed(self) -> bool:
        return not self.error and self.episodes > 0 and self.rate >= PASS_RATE

    def line(self) -> str:
        """``<ID>: scripted success 1.00 (3 of 3 seeds)``, or what went wrong."""
        if self.error:
            return f"{self.env_id}: {self.error}"
        text = f"{self.env_id}: scripted success {self.rate:.2f} ({self.successes} of {self.episodes} seeds)"
        if self.failures:
            reasons = sorted(set(self.failures))
            text += f"; failed: {', '.join(reasons)}"
        return text


@dataclass
class ArmCheck:
    """What :func:`check_arm` measured, task by task."""

    name: str
    tasks: list[TaskCheck]
    seconds: float

    @property
    def passed(self) -> bool:
        return all(t.passed for t in self.tasks)

    def failed(self) -> list[TaskCheck]:
        return [t for t in self.tasks if not t.passed]


def check_arm(path: str | Path, *, seeds: Sequence[int] = (0, 1, 2), tasks: Sequence[str] = CHECK_TASKS,
              register: bool = True) -> ArmCheck:
    """Run the scripted policies on an arm file's simulated IDs (see the module docstring).

    Args:
        path: the arm file.
        seeds: the episodes' seeds, one episode each per task.
        tasks: which of :data:`CHECK_TASKS` to try (push and pick-and-place only with a gripper).
        register: register the file for the check (and leave it registered as it was before); False:
            it is registered already.

    Raises:
        ArmFileError: the file does not load or register (one line naming the file and key).
    """
    import gymnasium as gym

    from rl_environments.arm_file import load_arm_file
    from rl_environments.arm_registry import register_arm, registered_arms, unregister_arm
    from rl_environments.manipulation_scripted import run_episode, scripted_policy

    spec = load_arm_file(path)
    unknown = [t for t in tasks if t not in CHECK_TASKS]
    if unknown:
        raise ValueError(f"tasks {unknown} are not among {list(CHECK_TASKS)}")
    before = registered_arms().get(spec.name)
    if register:
        register_arm(path, replace=True, tell_children=False)
    start = time.perf_counter()
    results: list[TaskCheck] = []
    try:
        for task in tasks:
            if task != "ReacherGoal" and spec.gripper is None:
                continue
            result = TaskCheck(f"{spec.name}{task}Sim-v0")
            results.append(result)
            try:
                env = gym.make(result.env_id, ee_action_type=True)
            except Exception as exc:  # noqa: BLE001 - any failure to make it is the finding, in one line
                result.error = f"cannot be made: {error_line(exc)}"
                continue
            try:
                policy = scripted_policy(env)
                for seed in seeds:
                    outcome = run_episode(env, policy, seed=seed)
                    result.episodes += 1
                    if outcome["is_success"]:
                        result.successes += 1
                    else:
                        result.failures.append(outcome["truncated_reason"] or "goal not met in time")
            except Exception as exc:  # noqa: BLE001 - as above
                result.error = f"failed in an episode: {error_line(exc)}"
            finally:
                env.close()
    finally:
        if register:
            unregister_arm(spec.name)
            if before is not None:
                register_arm(before.path, replace=True, check_chain=False, tell_children=False)
    return ArmCheck(spec.name, results, time.perf_counter() - start)


def refusal(check: ArmCheck) -> ArmFileError:
    """The one-line error of a check that failed: what failed, and where to look."""
    worst = check.failed()[0]
    hint = ("read the gripper's guesses (gripper.closed/open, manipulation.object_half_size) and arm.ee_link"
            if "Push" in worst.env_id or "PnP" in worst.env_id else
            "read arm.ee_link, reach.init_joint_pos and the goal box")
    return ArmFileError(f"{check.name}: the scripted check failed: {worst.line()}; fix: {hint}, or pass --no-check "
                        "to write the file anyway")
