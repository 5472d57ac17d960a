"""The real envs' safety rules, control loop and joint-state checks, unit-tested without ROS."""

from __future__ import annotations

import numpy as np
import pytest

from multiros.envs.real import ControlLoop, JointStateCache, SafetyRules, UnsafeCommandError
from multiros.envs.real.robot_link import JointState
from multiros.envs.real.safety import (
    FLOOR,
    JOINT_DELTA,
    JOINT_LIMITS,
    STATE_MISMATCH,
    WORKSPACE,
    description_joint_limits,
)
from rl_environments.arm_registry import arm_value
from rl_environments.robots.rx200_description import ARM_JOINTS, URDF_XACRO

CHAIN = arm_value("RX200").chain
HOME = np.zeros(5)


def rules(**kw) -> SafetyRules:
    args = dict(lower=CHAIN.lower, upper=CHAIN.upper, chain=CHAIN)
    args.update(kw)
    return SafetyRules(ARM_JOINTS, **args)


def test_targets_are_clamped_to_the_tighter_of_task_and_description_limits() -> None:
    lo, hi = description_joint_limits(str(URDF_XACRO), ARM_JOINTS, {"robot_name": "rx200"})
    np.testing.assert_allclose(lo, CHAIN.lower)
    r = SafetyRules(ARM_JOINTS, lower=[-1.0] * 5, upper=[10.0] * 5, description_lower=lo, description_upper=hi)
    d = r.check([-5.0, 0.5, 5.0, 0.0, 0.0], HOME)
    assert d.events == (JOINT_LIMITS,) and not d.refused
    np.testing.assert_allclose(d.target, [-1.0, 0.5, hi[2], 0.0, 0.0])
    assert d.as_info()["joint_limits"] is True and d.as_info()["refused"] is False


def test_a_tasks_joint_range_tightens_the_rules_and_keeps_the_others() -> None:
    r = rules(max_joint_delta=0.1, workspace_min=(-1, -1, 0), workspace_max=(1, 1, 1), floor_z=0.02,
              workspace_mode="refuse", path_samples=7, base_position=(0.1, 0.0, 0.2))
    task_lo = np.array([-1.0, -5.0, -1.0, -1.0, -1.0])
    task_hi = np.array([1.0, 1.0, 5.0, 1.0, 1.0])
    t = r.with_joint_limits(task_lo, task_hi)
    np.testing.assert_array_equal(t.lower, np.maximum(task_lo, CHAIN.lower))  # the tighter bound wins
    np.testing.assert_array_equal(t.upper, np.minimum(task_hi, CHAIN.upper))
    np.testing.assert_array_equal(r.lower, CHAIN.lower)  # the original rules are unchanged
    for name in ("joint_names", "max_joint_delta", "max_velocity", "base_position", "workspace_min",
                 "workspace_max", "floor_z", "workspace_mode", "path_samples", "chain"):
        assert repr(getattr(t, name)) == repr(getattr(r, name)), name
    d = t.check([2.0, 0.0, 0.0, 0.0, 0.0], HOME)
    assert JOINT_LIMITS in d.events


def test_per_command_change_is_capped_from_the_measured_position() -> None:
    r = rules(max_joint_delta=0.1)
    current = np.array([0.2, 0.0, 0.0, 0.0, 0.0])
    d = r.check([1.0, -1.0, 0.05, 0.0, 0.0], current)
    assert JOINT_DELTA in d.events
    np.testing.assert_allclose(d.target, [0.3, -0.1, 0.05, 0.0, 0.0])
    assert np.max(np.abs(d.target - current)) <= 0.1 + 1e-12
    np.testing.assert_array_equal(d.measured, current)  # what the cap was measured against
    current[0] = 9.0
    assert d.measured[0] == 0.2  # a copy: the caller's array may change afterwards
    assert r.check_move([0.1, 0.0, 0.0, 0.0, 0.0], HOME).measured.tolist() == list(HOME)


def test_a_forged_measurement_cannot_widen_the_cap_beyond_the_last_command() -> None:
    """The cap holds from the env's own previous command too: a state 1 rad off (forged) leaves a
    window of at most the cap around the last command, and 2 caps off refuses (state_mismatch)."""
    r = rules(max_joint_delta=0.15)
    previous = np.array([0.2, 0.0, 0.0, 0.0, 0.0])
    forged = previous + np.array([0.25, 0.0, 0.0, 0.0, 0.0])  # within 2 caps: the windows overlap
    d = r.check([1.5, 0.0, 0.0, 0.0, 0.0], forged, previous)
    assert not d.refused and d.target[0] == pytest.approx(0.35)  # previous + cap, not forged + cap (0.6)
    d = r.check([1.5, 0.0, 0.0, 0.0, 0.0], previous + np.array([1.0, 0, 0, 0, 0]), previous)
    assert d.refused and d.target is None and d.events == (STATE_MISMATCH,) and "waist" in d.reason
    assert d.as_info()["state_mismatch"] is True
    with pytest.raises(UnsafeCommandError, match="previous command"):
        r.check(HOME, HOME, [np.nan] * 5)


def test_measured_states_the_robot_cannot_be_in_are_implausible() -> None:
    r = rules(max_velocity=[1.0] * 5)
    assert r.plausible(HOME) is None
    assert "outside its limits" in r.plausible(np.array([1e5, 0, 0, 0, 0]))
    assert r.plausible(np.array([0.01, 0, 0, 0, 0]), HOME, 0.02) is None  # 0.5 rad/s: fine
    assert "jumped 1 rad in 0.01 s" in r.plausible(np.array([1.0, 0, 0, 0, 0]), HOME, 0.01)
    assert r.plausible(np.array([1.0, 0, 0, 0, 0]), HOME, 2.0) is None  # after a gap it may have moved
    cache = JointStateCache()
    cache.guard(r)
    ok = JointState(name=list(ARM_JOINTS), position=[0.0] * 5)
    assert cache.update(ok, now=10.0)
    jump = JointState(name=list(ARM_JOINTS), position=[1.0, 0, 0, 0, 0])
    assert not cache.update(jump, now=10.01) and "jumped" in cache.last_error
    assert cache.sample(ARM_JOINTS).position[0] == 0.0  # the forged value never reached the cache
    with pytest.raises(ValueError, match="max_velocity"):
        rules(max_velocity=[0.0] * 5)


def test_every_joint_of_a_partial_message_is_checked() -> None:
    """Issue 38: ``{name: [waist], position: [1e5]}`` was not checked (it lacks the other arm joints),
    was cached, and every true message after it was dropped as a jump for ~6 h."""
    cache = JointStateCache()
    cache.guard(rules(max_velocity=[1.0] * 5), fresh_for=0.25)
    assert cache.update(JointState(name=list(ARM_JOINTS), position=[0.0] * 5), now=10.0)
    assert not cache.update(JointState(name=["waist"], position=[1e5]), now=10.01)
    assert "waist at 1e+05 is outside its limits" in cache.last_error
    assert not cache.update(JointState(name=["elbow", "gripper"], position=[1.0, 0.0]), now=10.02)
    assert "elbow jumped 1 rad" in cache.last_error  # a partial message's jump, checked per joint
    assert cache.update(JointState(name=list(ARM_JOINTS), position=[0.01, 0, 0, 0, 0]), now=10.03)
    assert cache.sample(ARM_JOINTS).position.tolist() == [0.01, 0, 0, 0, 0]


def test_a_bad_value_that_got_in_is_replaced_within_fresh_for() -> None:
    """A value within the limits but not the robot's (the very first message, with no value to bound
    it) holds the driver's true messages off for ``fresh_for`` seconds at most, then they replace it."""
    cache = JointStateCache()
    cache.guard(rules(max_velocity=[1.0] * 5), fresh_for=0.25)
    assert cache.update(JointState(name=["waist"], position=[2.0]), now=10.0)  # nothing to bound it yet
    true = JointState(name=list(ARM_JOINTS), position=[0.0] * 5)
    t = 10.0
    while not cache.update(true, now=t):
        assert t < 10.25 + 1e-9 and "waist jumped" in cache.last_error
        t += 0.01
    assert t <= 10.26 and cache.sample(ARM_JOINTS).position[0] == 0.0
    assert cache.sample(ARM_JOINTS).received == pytest.approx(t)  # the whole arm is fresh again


def _stamped(t: float, q: list[float]) -> JointState:
    msg = JointState(name=list(ARM_JOINTS), position=q)
    msg.header.stamp.sec, msg.header.stamp.nanosec = int(t), int(round((t - int(t)) * 1e9))
    return msg


def test_a_late_message_is_dropped_and_the_next_fresh_one_is_not_a_jump() -> None:
    """Issue 51: a message delivered 0.1 s late (stamped at capture) replaced newer values, and the fresh
    messages after it were dropped as jumps (receipt times 10 ms apart, the arm moved 0.1 s worth) until
    the Real env gave up with a StaleStateError."""
    cache = JointStateCache()
    cache.guard(rules(max_velocity=[1.0] * 5), fresh_for=0.5)
    v = 0.9  # rad/s, the waist's speed (limit 1.0)
    for i in range(10):  # 100 Hz, on time
        t = 100.0 + 0.01 * i
        assert cache.update(_stamped(t, [v * (t - 100.0), 0, 0, 0, 0]), now=t)
    late = _stamped(99.99, [v * -0.01, 0, 0, 0, 0])  # captured before the first, arrives after the last
    assert not cache.update(late, now=100.095)
    assert cache.late_count == 1 and cache.malformed_count == 0
    assert cache.sample(ARM_JOINTS).position[0] == pytest.approx(v * 0.09)  # values never went back
    assert "1 joint_states message(s) stamped before values already received" in cache.describe_problem(ARM_JOINTS)
    # Delivery jitter: the message stamped 100.10 arrives 90 ms late, the one stamped 100.20 on time, 5 ms
    # after it. Its move of 90 mrad in 5 ms by receipt is a jump; 0.1 s by the stamps is within the limit.
    assert cache.update(_stamped(100.10, [v * 0.10, 0, 0, 0, 0]), now=100.19)
    assert cache.update(_stamped(100.20, [v * 0.20, 0, 0, 0, 0]), now=100.195)
    assert cache.malformed_count == 0
    assert cache.sample(ARM_JOINTS).position[0] == pytest.approx(v * 0.20)
    # The stamps lengthen the allowed time only up to fresh_for: a forged far-future stamp is no licence.
    assert not cache.update(_stamped(300.0, [1.5, 0, 0, 0, 0]), now=100.2) and "jumped" in cache.last_error


def test_a_clock_that_goes_back_is_taken_after_a_few_messages() -> None:
    """A driver whose clock jumps back (restarted, simulated time reset) is not dropped for ever: the
    third message in a row stamped before the cache's is taken as the new clock."""
    cache = JointStateCache()
    cache.guard(rules(max_velocity=[1.0] * 5), fresh_for=0.5)
    assert cache.update(_stamped(50.0, [0.0] * 5), now=10.0)
    assert not cache.update(_stamped(49.5, [0.0] * 5), now=10.01)
    assert not cache.update(_stamped(49.51, [0.0] * 5), now=10.02)
    assert cache.update(_stamped(49.52, [0.0] * 5), now=10.03)
    assert cache.update(_stamped(49.53, [0.0] * 5), now=10.04) and cache.late_count == 2
    assert cache.update(_stamped(2.0, [0.0] * 5), now=10.05)  # more than MAX_LATE back: a new clock at once
    assert cache.sample(ARM_JOINTS).stamp == pytest.approx(2.0)


def test_a_pinned_cache_takes_only_its_driver_s_messages() -> None:
    cache = JointStateCache()
    driver, other = bytes(range(16)), bytes(16)
    msg = JointState(name=list(ARM_JOINTS), position=[0.0] * 5)
    assert cache.update(msg, now=1.0, source=other)  # not pinned yet: heard, counted as a source
    assert cache.update(msg, now=1.1, source=driver)
    assert cache.sources(within=0.5, now=1.2) == [driver, other]
    cache.pin(driver)
    assert cache.names == ()  # a new identity drops what was cached before it was pinned
    forged = JointState(name=list(ARM_JOINTS), position=[0.3] * 5)
    assert not cache.update(forged, now=1.3, source=other)
    assert cache.sample(ARM_JOINTS) is None and cache.foreign_count == 1
    assert "from a publisher other than the driver (identity 000000000000" in cache.describe_problem(ARM_JOINTS)
    assert cache.update(msg, now=1.4, source=driver) and cache.sample(ARM_JOINTS).position[0] == 0.0
    cache.pin(driver)
    assert cache.names == tuple(ARM_JOINTS)  # the same identity again keeps the values


def test_the_first_move_is_timed_from_anywhere_the_arm_can_be() -> None:
    lo, hi = description_joint_limits(str(URDF_XACRO), ARM_JOINTS, {"robot_name": "rx200"})
    r = SafetyRules(ARM_JOINTS, lower=[-1.0] * 5, upper=[1.0] * 5, description_lower=lo, description_upper=hi)
    worst = r.worst_case_distance(HOME)  # from the description's range, not the task's tighter one
    np.testing.assert_allclose(worst, np.maximum(-lo, hi) + 0.05)
    assert np.isinf(SafetyRules(["j"], lower=[-np.inf], upper=[np.inf]).worst_case_distance([0.0])[0])


@pytest.mark.parametrize("bad", [[np.nan, 0, 0, 0, 0], [np.inf, 0, 0, 0, 0], [0, 0, 0, 0]])
def test_nan_infinite_or_wrong_length_targets_raise(bad: list[float]) -> None:
    with pytest.raises(UnsafeCommandError, match="nothing was sent"):
        rules().check(bad, HOME)


def test_floor_projects_the_motion_back_to_the_limit() -> None:
    z_home = float(CHAIN.fk_position(HOME)[2])
    r = rules(floor_z=z_home - 0.05)
    down = np.array([0.0, 1.2, 0.6, 0.0, 0.0])  # shoulder and elbow forward: the gripper goes down
    assert CHAIN.fk_position(down)[2] < z_home - 0.05
    d = r.check(down, HOME)
    assert FLOOR in d.events and not d.refused
    z = float(CHAIN.fk_position(d.target)[2])
    assert z_home - 0.05 - 1e-6 <= z < z_home - 0.04  # as far as allowed, not further
    frac = d.target[1:3] / down[1:3]
    np.testing.assert_allclose(frac, frac[0])  # along the requested motion


def test_refuse_mode_sends_nothing_and_says_why() -> None:
    z_home = float(CHAIN.fk_position(HOME)[2])
    r = rules(floor_z=z_home - 0.05, workspace_mode="refuse")
    d = r.check([0.0, 1.2, 0.6, 0.0, 0.0], HOME)
    assert d.refused and d.target is None and "refused" in d.reason and d.as_info()["floor"] is True


def test_workspace_box_and_a_robot_outside_may_only_move_back_in() -> None:
    ee = CHAIN.fk_position(HOME)
    r = rules(workspace_min=ee - [0.3, 0.3, 0.3], workspace_max=ee + [0.3, 0.3, 0.01])
    up = np.array([0.0, -0.5, -0.5, 0.0, 0.0])  # raises the gripper
    d = r.check(up, HOME)
    assert WORKSPACE in d.events and d.ee_position[2] <= ee[2] + 0.01 + 1e-6
    # Started above the box: moving further up is refused, moving down is allowed.
    r2 = rules(workspace_min=ee - [0.3, 0.3, 0.3], workspace_max=ee + [0.3, 0.3, -0.02])
    assert r2.check(up, HOME).refused
    assert not r2.check([0.0, 0.2, 0.2, 0.0, 0.0], HOME).refused


def test_long_moves_are_checked_along_the_whole_path() -> None:
    z_home = float(CHAIN.fk_position(HOME)[2])
    r = rules(floor_z=z_home - 0.05, max_joint_delta=0.1)
    d = r.check_move([0.0, 1.2, 0.6, 0.0, 0.0], HOME)
    assert d.refused and "floor" in d.reason
    ok = r.check_move([1.0, 0.0, 0.0, 0.0, 0.0], HOME)  # no per-command cap on resets
    np.testing.assert_allclose(ok.target, [1.0, 0, 0, 0, 0])


def test_rules_refuse_inconsistent_configuration() -> None:
    with pytest.raises(ValueError, match="kinematic chain"):
        SafetyRules(ARM_JOINTS, lower=CHAIN.lower, upper=CHAIN.upper, floor_z=0.0)
    with pytest.raises(ValueError, match="empty"):
        SafetyRules(ARM_JOINTS, lower=[1.0] * 5, upper=[0.0] * 5)
    with pytest.raises(ValueError, match="workspace_mode"):
        rules(workspace_mode="ignore")


def test_control_loop_paces_and_validates() -> None:
    loop = ControlLoop(20.0, 0.0)
    assert loop.cycle == pytest.approx(0.05)
    loop.last_observe = 100.0
    assert loop.observe_time(100.0) == pytest.approx(100.05)
    assert ControlLoop(10.0, 0.3).observe_time(5.0) == pytest.approx(5.3)
    with pytest.raises(ValueError, match="shorter than one loop period"):
        ControlLoop(10.0, 0.05)
    with pytest.raises(ValueError, match="environment_loop_rate"):
        ControlLoop(0.0)
    calls = []

    def watchdog() -> None:
        calls.append(1)
        if len(calls) == 3:
            raise TimeoutError("stale")

    with pytest.raises(TimeoutError):
        ControlLoop(1.0).wait(__import__("time").monotonic(), watchdog)  # aborts long before the 1 s cycle


def _js(names, pos, vel=(), eff=()):
    return JointState(name=list(names), position=list(pos), velocity=list(vel), effort=list(eff))


@pytest.mark.parametrize(("msg", "reason"), [
    (_js(["a", "b"], [0.0]), "2 names but 1 positions"),
    (_js(["a", "b"], [0.0, float("nan")]), "NaN"),
    (_js(["a", "b"], [0.0, 1.0], [1.0]), "velocity"),
    (_js(["a", "a"], [0.0, 1.0]), "repeated"),
    (_js(["a"], [1e9]), "beyond"),
])
def test_malformed_joint_states_are_dropped_with_the_reason(msg, reason) -> None:
    cache = JointStateCache()
    assert cache.update(_js(["a", "b"], [0.1, 0.2], [0.0, 0.0]), now=1.0)
    assert not cache.update(msg, now=2.0)
    assert reason in cache.last_error and cache.malformed_count == 1
    s = cache.sample(["b", "a"])
    np.testing.assert_allclose(s.position, [0.2, 0.1])
    assert s.received == 1.0  # the bad message did not refresh the state
    assert "malformed" in cache.describe_problem(["a", "b"])
