"""``uniros-fake-robot --gap PROFILE``: a stand-in robot with a measurable reality gap.

The profile (parsing, errors), the joints' model at the :class:`FakeHardware` level on a fake clock
(no ROS), and what ``joint_states`` suffers over the wire (a child process on a private router, never
port 7447, stopped by PID). The last test shows the stand-in reproduces the issue's reset failure: with
``--gap hard`` the RX200's shoulder and elbow settle about 0.03 rad short of a reset pose, beyond the
0.02 rad a reset used to demand.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest
from test_fake_robot import _CWD, ARM, JointState, Probe, _goal, _send

from multiros.hardware import FakeHardware, load_robot_spec
from multiros.hardware.gap import (
    KEYS,
    PROFILES,
    GapProfile,
    GapProfileError,
    StateGap,
    gap_generators,
    load_gap_profile,
    parse_gap_assignments,
)
from multiros.hardware.process import FakeRobotProcess
from multiros.ros import Context
from multiros.sim.launch import private_context

DT = 0.01


# ------------------------------------------------------------------------------ the profile
def test_shipped_profiles_have_the_documented_values() -> None:
    assert PROFILES["none"] == GapProfile() and not PROFILES["none"].acts_on_joints
    assert not PROFILES["none"].acts_on_messages
    hard = PROFILES["hard"]
    assert (hard.latency, hard.time_constant, hard.backlash, hard.droop, hard.offset, hard.noise, hard.drop,
            hard.late, hard.late_by, hard.jitter) == (0.1, 0.25, 0.005, 0.03, 0.01, 0.004, 0.05, 0.05, 0.1, 0.3)
    mild = PROFILES["mild"]
    assert (mild.latency, mild.time_constant, mild.backlash, mild.droop, mild.offset, mild.noise, mild.drop,
            mild.late, mild.late_by, mild.jitter) == (0.02, 0.12, 0.002, 0.01, 0.005, 0.001, 0.01, 0.01, 0.05, 0.1)
    assert hard.droop_joints == mild.droop_joints == (1, 2)


def test_a_yaml_file_and_overrides(tmp_path: Path) -> None:
    path = tmp_path / "gap.yaml"
    path.write_text("latency: 0.05\nnoise: 1e-3\ndroop: 0.02\ndroop_joints: [1]\n")
    profile = load_gap_profile(path)
    assert profile == GapProfile(latency=0.05, noise=0.001, droop=0.02, droop_joints=(1,))
    over = load_gap_profile("hard", parse_gap_assignments(["drop=0", "droop_joints=1,2,3", "late_by=0.2"]))
    assert over.drop == 0.0 and over.droop_joints == (1, 2, 3) and over.late_by == 0.2 and over.latency == 0.1
    assert load_gap_profile("mild", {"droop_joints": "[2]"}).droop_joints == (2,)
    empty = tmp_path / "empty.yaml"
    empty.write_text("")
    assert load_gap_profile(empty) == GapProfile()


@pytest.mark.parametrize(("text", "overrides", "match"), [
    ("latncy: 0.1\n", None, r"unknown gap key\(s\) \['latncy'\]; the keys are \['latency', 'time_constant'"),
    ("- 1\n- 2\n", None, "must be a YAML mapping of gap keys"),
    ("drop: 1.5\n", None, r"gap key 'drop': must be a fraction in \[0, 1\], got 1.5"),
    ("noise: -0.1\n", None, r"gap key 'noise': must be a finite number >= 0"),
    ("offset: .nan\n", None, r"gap key 'offset': must be a finite number >= 0"),
    ("latency: 100\n", None, r"gap key 'latency': must be at most 10 s"),
    ("backlash: true\n", None, r"gap key 'backlash': must be a finite number >= 0"),
    ("droop: abc\n", None, r"gap key 'droop': must be a number, got 'abc'"),
    ("droop_joints: [1, -1]\n", None, r"gap key 'droop_joints': must be a list of arm joint indices"),
    ("droop_joints: [1, 1]\n", None, r"gap key 'droop_joints': indices repeat"),
    ("a: [\n", None, "cannot be read"),
    ("{}\n", {"jitter": "x"}, r"gap key 'jitter': must be a number, got 'x'"),
    ("{}\n", {"nope": "1"}, r"--gap-set: unknown gap key\(s\) \['nope'\]"),
], ids=["unknown", "not-mapping", "fraction", "negative", "nan", "too-long", "bool", "not-number", "index",
        "repeat", "bad-yaml", "override", "override-key"])
def test_bad_profiles_are_one_line_naming_the_key(tmp_path: Path, text: str, overrides, match: str) -> None:
    path = tmp_path / "gap.yaml"
    path.write_text(text)
    with pytest.raises(GapProfileError, match=match) as info:
        load_gap_profile(path, overrides)
    assert "\n" not in str(info.value)


def test_unknown_names_and_bad_assignments() -> None:
    with pytest.raises(GapProfileError, match=r"'rough': neither a shipped profile \(none, mild, hard\) nor a YAML"):
        load_gap_profile("rough")
    for bad in ["drop", "=1", "drop="]:
        with pytest.raises(GapProfileError, match="must look like KEY=VALUE"):
            parse_gap_assignments([bad])
    assert set(KEYS) == {"latency", "time_constant", "backlash", "droop", "droop_joints", "offset", "noise", "drop",
                         "late", "late_by", "jitter"}


@pytest.mark.parametrize("program", [["multiros.hardware.fake_robot", "--robot", "rx200"],
                                     ["uniros.fake_robot", "--robot", "vx300s"]], ids=["plain", "arm-file"])
def test_the_command_line_refuses_a_bad_gap_with_exit_code_2(program: list[str]) -> None:
    out = subprocess.run([sys.executable, "-m", *program, "--router", "none", "--gap", "hard", "--gap-set", "drop=2"],
                         capture_output=True, text=True, timeout=60, cwd=_CWD)
    assert out.returncode == 2
    assert out.stderr.strip() == "uniros-fake-robot: gap key 'drop': must be a fraction in [0, 1], got 2.0"


# ------------------------------------------------------------------------------ the joints (fake clock, no ROS)
class Clock:
    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


def _hardware(gap: GapProfile | None, *, seed: int = 0,
              time_constant: float | None = None) -> tuple[FakeHardware, Clock]:
    """The RX200 with its forward position controller over the arm (waist, shoulder, elbow, ...), at 0."""
    clock = Clock()
    spec = load_robot_spec("rx200", initial_positions={j: 0.0 for j in ARM})
    hw = FakeHardware(spec, time_constant=time_constant, clock=clock, gap=gap, seed=seed)
    hw.start_controllers()
    hw.cm.switch(["arm_position_controller"], ["arm_controller"], time=clock.t)
    return hw, clock


def _command(hw: FakeHardware, clock: Clock, arm: list[float]) -> None:
    hw.cm.set_command("arm_position_controller", arm, clock.t)


def _run(hw: FakeHardware, clock: Clock, seconds: float,
         each: Callable[[], None] | None = None) -> None:
    for _ in range(int(round(seconds / DT))):
        clock.t += DT
        hw.update(DT)
        if each is not None:
            each()


def test_latency_no_motion_before_it() -> None:
    hw, clock = _hardware(GapProfile(latency=0.1), time_constant=0.05)
    _command(hw, clock, [0.2, 0.0, 0.0, 0.0, 0.0])
    sent = clock.t
    moved: list[float] = []

    def watch() -> None:
        if hw.hw.position[0] != 0.0 and not moved:
            moved.append(clock.t - sent)

    _run(hw, clock, 0.5, watch)
    assert moved and 0.1 <= moved[0] <= 0.1 + 2 * DT + 1e-9, f"first motion {moved} s after the command"
    assert hw.hw.position[0] > 0.15


def test_lag_from_the_profiles_time_constant() -> None:
    hw, clock = _hardware(GapProfile(time_constant=0.2))
    assert hw.time_constant == 0.2
    assert FakeHardware(load_robot_spec("rx200"), time_constant=0.05, gap=GapProfile(time_constant=0.2)
                        ).time_constant == 0.05  # an explicit time constant wins
    _command(hw, clock, [0.1, 0.0, 0.0, 0.0, 0.0])
    _run(hw, clock, 0.2)  # one time constant
    assert hw.hw.position[0] == pytest.approx(0.1 * (1.0 - math.exp(-1.0)), rel=1e-6)


def test_droop_settles_short_on_the_side_it_came_from() -> None:
    hw, clock = _hardware(GapProfile(droop=0.03), time_constant=0.05)
    _command(hw, clock, [0.3, 0.3, -0.3, 0.3, 0.0])
    _run(hw, clock, 2.0)
    np.testing.assert_allclose(hw.hw.position[:4], [0.3, 0.27, -0.27, 0.3], atol=1e-6)  # shoulder and elbow short
    _command(hw, clock, [0.0, 0.0, 0.0, 0.0, 0.0])  # back: short on the other side
    _run(hw, clock, 2.0)
    np.testing.assert_allclose(hw.hw.position[:3], [0.0, 0.03, -0.03], atol=1e-6)
    held = hw.hw.position.copy()
    # Shoulder: a command within the droop of where it stands does not move it; elbow: beyond, it does.
    _command(hw, clock, [0.0, 0.01, -0.1, 0.0, 0.0])
    _run(hw, clock, 1.0)
    assert hw.hw.position[1] == held[1] and hw.hw.position[2] == pytest.approx(-0.07, abs=1e-6)


def test_droop_joints_beyond_the_arm_are_refused() -> None:
    with pytest.raises(GapProfileError, match=r"gap key 'droop_joints': \[5\] out of range for the 5 commanded arm"):
        _hardware(GapProfile(droop=0.01, droop_joints=(1, 5)))


def test_backlash_a_dead_band_on_direction_change() -> None:
    hw, clock = _hardware(GapProfile(backlash=0.01), time_constant=0.05)
    _command(hw, clock, [0.2, 0.0, 0.0, 0.0, 0.0])
    _run(hw, clock, 2.0)
    assert hw.hw.position[0] == pytest.approx(0.195, abs=1e-6)  # the link trails the servo by half the play
    _command(hw, clock, [0.192, 0.0, 0.0, 0.0, 0.0])  # reversing by less than the play: the link stays
    _run(hw, clock, 2.0)
    assert hw.hw.position[0] == pytest.approx(0.195, abs=1e-9)
    _command(hw, clock, [0.1, 0.0, 0.0, 0.0, 0.0])
    _run(hw, clock, 2.0)
    assert hw.hw.position[0] == pytest.approx(0.105, abs=1e-6)


def test_offsets_between_encoder_and_truth_and_the_same_seed_the_same_robot() -> None:
    gap = GapProfile(offset=0.01)
    hw, clock = _hardware(gap, seed=7, time_constant=0.05)
    offsets = hw.offsets
    assert np.all(np.abs(offsets[:5]) <= 0.01) and np.all(offsets[:5] != 0) and offsets[5] == 0.0  # arm only
    np.testing.assert_array_equal(_hardware(gap, seed=7)[0].offsets, offsets)
    assert not np.array_equal(_hardware(gap, seed=8)[0].offsets, offsets)
    _command(hw, clock, [0.2, -0.1, 0.1, 0.0, 0.0])
    _run(hw, clock, 2.0)
    encoder, _, _ = hw.published_state()
    truth, _, _ = hw.true_state()
    # The servo closes its loop on the encoder: joint_states reads the command, the truth is off by the offset.
    np.testing.assert_allclose(encoder[:5], [0.2, -0.1, 0.1, 0.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(np.subtract(encoder, truth)[:6], offsets, atol=1e-12)
    assert truth[6] == pytest.approx(-truth[5])  # the mimic finger follows the true leader


def test_no_gap_and_the_none_profile_are_todays_joints_bit_for_bit() -> None:
    runs = []
    for gap in (None, PROFILES["none"]):
        hw, clock = _hardware(gap)
        _command(hw, clock, [0.3, -0.2, 0.4, 0.1, 100.0])
        trace = []
        _run(hw, clock, 0.5, lambda hw=hw, trace=trace: trace.append(hw.hw.position.copy()))
        runs.append(np.array(trace))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_the_messages_stream_draws_drops_late_noise_and_jitter() -> None:
    profile = GapProfile(drop=0.2, late=0.1, late_by=0.05, noise=0.01, jitter=0.4)
    sensing = StateGap(profile, 0.01, gap_generators(3)[1])
    fates = [sensing.fate() for _ in range(20_000)]
    assert fates.count(StateGap.DROP) / len(fates) == pytest.approx(0.2, abs=0.015)
    assert fates.count(StateGap.LATE) / len(fates) == pytest.approx(0.1, abs=0.015)
    jitter = np.array([sensing.jitter() for _ in range(5_000)])
    assert np.all(np.abs(jitter) <= 0.002) and jitter.std() == pytest.approx(0.004 / math.sqrt(12), rel=0.05)
    noise = np.array(sensing.noisy([0.0] * 10_000))
    assert noise.std() == pytest.approx(0.01, rel=0.05)
    again = StateGap(profile, 0.01, gap_generators(3)[1])
    assert [again.fate() for _ in range(100)] == fates[:100]  # the same seed, the same messages


# ------------------------------------------------------------------------------ over the wire
@pytest.fixture(scope="module")
def graph() -> Iterator[Context]:
    ctx = private_context()
    yield ctx
    ctx.try_shutdown()


class Truth:
    """The fake robot's ground truth topic, recorded on a probe's node."""

    def __init__(self, probe: Probe, topic: str) -> None:
        self.lock = threading.Lock()
        self.messages: list[object] = []
        probe.node.create_subscription(JointState, topic, self._on, 200)

    def _on(self, msg: object) -> None:
        with self.lock:
            self.messages.append(msg)


def _stamp(msg) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def _wait(predicate: Callable[[], bool], timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"{what} not within {timeout} s")
        time.sleep(0.02)


@pytest.mark.multiprocess
def test_drops_late_messages_noise_and_offsets_on_the_wire(graph: Context) -> None:
    gap = ["--gap", "none", "--gap-set", "drop=0.2", "--gap-set", "late=0.2", "--gap-set", "late_by=0.1",
           "--gap-set", "noise=0.01", "--gap-set", "offset=0.02", "--gap-set", "jitter=0.5", "--gap-seed", "5"]
    with FakeRobotProcess("rx200", context=graph, args=["--log-level", "WARNING", "--namespace", "gappy", *gap],
                          cwd=_CWD):
        probe = Probe(graph, ns="/gappy")
        truth = Truth(probe, "/gappy/controller_manager/ground_truth/joint_states")
        try:
            # 3 s of captures, and 0.7 s more for the late messages of the last ones (0.1 s late)
            _wait(lambda: len(truth.messages) >= 420, 30.0, "420 ground truth messages")
            with truth.lock:
                truths = {_stamp(m): m for m in truth.messages[50:350]}  # 3 s of captures, none at the edges
            with probe.lock:
                states = [m for _, m in probe.states]
        finally:
            probe.close()
    stamps = [_stamp(m) for m in states]
    got = {s: m for s, m in zip(stamps, states) if s in truths}
    drop = 1.0 - len(got) / len(truths)
    assert 0.1 < drop < 0.32, f"{drop:.3f} of joint_states dropped, --gap-set drop=0.2"
    # A late message arrives after newer ones (0.1 s = 10 publish periods late), stamped when captured.
    late = {s for i, s in enumerate(stamps) if i and s < max(stamps[:i]) and s in truths}
    assert 0.1 < len(late) / len(truths) < 0.32, f"{len(late) / len(truths):.3f} late, --gap-set late=0.2"
    # Encoder minus truth: the calibration offsets (the arm's, from the seed) plus the position noise.
    diff = np.array([np.subtract(got[s].position, truths[s].position) for s in sorted(got)])
    offsets = FakeHardware(load_robot_spec("rx200"), gap=GapProfile(offset=0.02), seed=5).offsets
    np.testing.assert_allclose(diff.mean(axis=0)[:6], offsets, atol=0.004)
    assert diff.std(axis=0).mean() == pytest.approx(0.01, rel=0.15)
    assert list(truths[next(iter(truths))].name) == [*ARM, "left_finger", "right_finger"]
    periods = np.diff(sorted(truths)) * 1e-9
    assert 0.009 < float(np.median(periods)) < 0.011  # the rate is kept under jitter


def _settled(probe: Probe, joints: list[str], timeout: float = 20.0) -> np.ndarray:
    """The arm joints' mean position over 0.5 s once they have stopped (noise averages out)."""
    def still() -> bool:
        _, msg = probe.wait_states(1)[-1]
        return float(np.max(np.abs(msg.velocity))) < 1e-4

    _wait(still, timeout, "the arm at rest")
    probe.clear()
    states = probe.wait_states(40)
    names = list(states[0][1].name)
    return np.mean([[m.position[names.index(j)] for j in joints] for _, m in states], axis=0)


@pytest.mark.multiprocess
@pytest.mark.slow
def test_the_hard_gap_reproduces_the_reset_that_never_reaches_002_rad(graph: Context) -> None:
    """The issue's failure: against an arm whose shoulder and elbow droop 0.03 rad, a reset to
    ``reach.init_joint_pos`` settles beyond the 0.02 rad a reset used to require, on those joints only."""
    from rl_environments.arm_registry import registered_arms

    arm = registered_arms()["RX200"]
    args = ["--arm", str(arm.path), "--gap", "hard", "--log-level", "WARNING"]
    with FakeRobotProcess(None, context=graph, args=args, namespace=arm.real.namespace, timeout_sec=90.0, cwd=_CWD,
                          module="uniros.fake_robot"):
        probe = Probe(graph, ns=arm.real.namespace)
        try:
            assert probe.action.wait_for_server(10.0)
            goal = list(arm.reach["init_joint_pos"])
            handle = _send(probe, _goal(goal, 2.0, joints=list(arm.joints)))
            assert handle.accepted
            handle.get_result(timeout_sec=15.0)
            error = np.abs(_settled(probe, list(arm.joints)) - goal)
        finally:
            probe.close()
    # droop 0.03 plus half the backlash (0.0025) on shoulder and elbow; the other joints within the backlash
    assert np.all((error[1:3] > 0.025) & (error[1:3] < 0.04)), f"settled errors {np.round(error, 4)}"
    assert np.all(error[[0, 3, 4]] < 0.006), f"settled errors {np.round(error, 4)}"
    assert error.max() > 0.02  # today's reset tolerance: a reset to this pose cannot succeed


def _cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime + stime


@pytest.mark.multiprocess
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads the child's CPU time from /proc")
def test_a_stalled_robot_with_a_gap_stops_everything_and_idles(graph: Context) -> None:
    args = ["--log-level", "ERROR", "--namespace", "stally", "--stall-after", "0.5", "--gap", "hard",
            "--gap-set", "late=0.5", "--gap-set", "jitter=1"]
    with FakeRobotProcess("rx200", context=graph, args=args, cwd=_CWD) as robot:
        probe = Probe(graph, ns="/stally")
        truth = Truth(probe, "/stally/controller_manager/ground_truth/joint_states")
        try:
            _wait(lambda: len(truth.messages) > 0, 10.0, "the truth")

            def quiet() -> bool:  # nothing for 0.3 s: neither joint_states nor the truth
                seen = (len(truth.messages), len(probe.states))
                deadline = time.monotonic() + 0.3
                while time.monotonic() < deadline:
                    time.sleep(0.02)
                return (len(truth.messages), len(probe.states)) == seen

            _wait(quiet, 10.0, "joint_states and the truth stopped by --stall-after")
            cpu, wall = _cpu_seconds(robot.pid), time.monotonic()
            assert probe.controllers()["arm_controller"] == "active"  # the services still answer
            _wait(lambda: time.monotonic() - wall > 1.0, 5.0, "a second")
            busy = (_cpu_seconds(robot.pid) - cpu) / (time.monotonic() - wall)
            assert busy < 0.2, f"the stalled fake robot used {busy:.0%} of a core (a loop waking for nothing)"
        finally:
            probe.close()
