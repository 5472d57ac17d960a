"""The scripted pick-and-place's carry ramp: how fast a held cube starts to move (no simulation: the
policy reads only the observation)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from rl_environments.arm_task import ArmTask
from rl_environments.manipulation_scripted import (
    FAST_CARRY_RAMP,
    ScriptedPickAndPlace,
    ScriptedPush,
    ScriptedReach,
    scripted_object_policy,
    scripted_policy,
)
from rl_environments.reach_task import ReachTask

HALF = 0.024


def _obs(ee, obj, fingers=(0.02, 0.02), goal=(0.3, 0.3, 0.3)) -> dict[str, np.ndarray]:
    state = np.zeros(31)
    state[0:3], state[3:6], state[9:11] = ee, obj, fingers
    return {"observation": state, "desired_goal": np.asarray(goal, float), "achieved_goal": np.asarray(obj, float)}


EE, OBJ = np.array([0.4, 0.0, 0.428]), np.array([0.4, 0.0, 0.423])


def _carry_speeds(policy: ScriptedPickAndPlace, steps: int, grasp: bool = True) -> list[float]:
    """The largest EE action of each step of a carry towards a far goal, the cube held 5 mm below the EE
    (``grasp``: from a new episode, closing on the cube first)."""
    ee, obj = EE, OBJ
    if grasp:
        policy.reset()
        for _ in range(4):  # close on the cube until the fingers count as squeezing it
            action = policy(_obs(ee, obj))
            assert action[3] == -1.0 and not action[:3].any()
    speeds = []
    for _ in range(steps):
        action = policy(_obs(ee, obj))
        assert action[3] == -1.0  # still holding
        speeds.append(float(np.abs(action[:3]).max()))
    return speeds


def test_without_a_ramp_the_carry_starts_at_full_speed():
    speeds = _carry_speeds(ScriptedPickAndPlace(ee_delta_coeff=0.02, half=HALF, closed=0.0), 3)
    assert speeds == [1.0, 1.0, 1.0]


def test_a_ramp_starts_the_carry_at_0_3_and_reaches_full_speed_after_its_steps():
    speeds = _carry_speeds(ScriptedPickAndPlace(ee_delta_coeff=0.04, half=HALF, closed=0.0, carry_ramp=10), 12)
    assert speeds[0] == pytest.approx(0.3)
    assert all(b > a for a, b in zip(speeds[:10], speeds[1:10]))  # speeding up, step by step
    assert speeds[9] < 1.0 and speeds[10:] == [1.0, 1.0]


def test_the_ramp_starts_again_after_the_cube_is_let_go():
    policy = ScriptedPickAndPlace(ee_delta_coeff=0.04, half=HALF, closed=0.0, carry_ramp=10)
    first = _carry_speeds(policy, 5)
    assert first[-1] > 0.3
    # the fingers close on nothing for a step (the cube slipped), then squeeze it again: a new carry
    action = policy(_obs(EE, OBJ, fingers=(0.0, 0.0)))
    assert action[3] == -1.0 and not action[:3].any()
    assert _carry_speeds(policy, 5, grasp=False) == first


def test_scripted_policy_ramps_only_arms_whose_ee_moves_more_than_3_cm_a_step():
    def task(coeff: float, kind: str) -> SimpleNamespace:
        return SimpleNamespace(ee_action_type=True, KIND=kind, ee_delta_coeff=coeff, half=HALF,
                               gripper_range=(0.0, 0.04))

    assert scripted_object_policy(task(0.04, "pnp")).carry_ramp == FAST_CARRY_RAMP  # UR5e, Panda
    assert scripted_object_policy(task(0.025, "pnp")).carry_ramp == 0  # RX200, VX300S, NED2: unchanged
    push = scripted_object_policy(task(0.04, "push"))
    assert isinstance(push, ScriptedPush) and push.carry_ramp == FAST_CARRY_RAMP


def test_a_task_without_a_scripted_policy_is_refused_not_driven_as_a_reach():
    class Stack(ArmTask):  # a task of your own that writes no scripted policy
        NAME = "stack"

    unknown = SimpleNamespace(unwrapped=SimpleNamespace(task=object.__new__(Stack)))
    with pytest.raises(ValueError, match="no scripted policy for the task 'stack'"):
        scripted_policy(unknown)
    with pytest.raises(ValueError, match="is not an arm env with a task"):
        scripted_policy(SimpleNamespace(unwrapped=SimpleNamespace()))
    reach = object.__new__(ReachTask)
    reach.ee_action_type, reach.ee_delta_coeff = True, 0.04
    assert isinstance(scripted_policy(SimpleNamespace(unwrapped=SimpleNamespace(task=reach))), ScriptedReach)


def test_a_negative_ramp_is_refused():
    with pytest.raises(ValueError, match="carry_ramp must be >= 0"):
        ScriptedPickAndPlace(carry_ramp=-1)
