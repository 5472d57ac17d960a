"""``uniros sysid``: bags written with rosbags' writer from signals of a known lag, latency, gain and
offset (plus noise) are read back (sqlite3, MCAP, ROS 1), fitted, and written into an arm file.

Fast: a 20 s signal per bag, a simulated first-order lag behind a delay at 1 ms steps sampled at
100 Hz; the end-to-end check against ``uniros-fake-robot`` is ``benchmarks/bench_sysid.py``.
"""

from __future__ import annotations

import hashlib
import math
import shutil
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("rosbags")

from rosbags.rosbag2 import StoragePlugin, Writer  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

from uniros import sysid  # noqa: E402
from uniros.sysid_bag import BagError, BagTopics, default_topics, read_recording  # noqa: E402
from uniros.sysid_fit import CommandTrace, FitError, Recording, fit_recording, setpoints  # noqa: E402

RX200 = Path(__file__).resolve().parents[2] / "config" / "arms" / "rx200.yaml"
JOINTS = ("waist", "shoulder", "elbow", "wrist_angle", "wrist_rotate")
NS = "/rx200"
STATES, TRAJ, FWD = f"{NS}/joint_states", f"{NS}/arm_controller/joint_trajectory", f"{NS}/arm_controller/commands"
STORE = get_typestore(Stores.ROS2_HUMBLE)
T0 = 1_700_000_000.0  # the recording's wall clock (s)


# -- synthetic robots ------------------------------------------------------------------------------
def simulate(*, seconds: float = 20.0, latency: float = 0.1,
             tau: Sequence[float] = (0.25, 0.2, 0.3, 0.15, 0.25), gain: Sequence[float] = (1.0, 0.95, 1.0, 1.0, 1.05),
             offset: Sequence[float] = (0.02, -0.01, 0.0, 0.0, 0.0),
             noise: float = 0.002, rate: float = 100.0, amplitude: Sequence[float] = (0.4,) * 5,
             seed: int = 0, vlimit: Sequence[float] | None = None, droop: float = 0.0,
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Step commands every 0.4-1.2 s, the joints as a lag behind a delay (1 ms Euler steps).
    Returns command times, command values ``(M, J)``, state times, state positions ``(N, J)``."""
    rng = np.random.default_rng(seed)
    amp = np.asarray(amplitude)
    starts = [0.0]
    while starts[-1] < seconds:
        starts.append(starts[-1] + rng.uniform(0.4, 1.2))
    cmd_t = np.array(starts)
    cmd_u = rng.uniform(-1, 1, (cmd_t.size, len(amp))) * amp
    h = 1e-3
    t = np.arange(0.0, seconds, h)
    k = np.searchsorted(cmd_t, t - latency, side="right") - 1
    side = np.sign(np.diff(cmd_u, axis=0, prepend=cmd_u[:1]))  # each command's approach: short by droop
    u = (cmd_u - droop * side)[np.maximum(k, 0)]
    tau_a, g, off = np.asarray(tau), np.asarray(gain), np.asarray(offset)
    y = np.empty_like(u)
    y[0] = g * cmd_u[0] + off
    cap = None if vlimit is None else np.asarray(vlimit) * h
    for n in range(t.size - 1):
        step = (g * u[n] + off - y[n]) / tau_a * h
        y[n + 1] = y[n] + (step if cap is None else np.clip(step, -cap, cap))
    st = np.arange(0.0, seconds - 0.01, 1.0 / rate)
    sy = np.stack([np.interp(st, t, y[:, j]) for j in range(y.shape[1])], axis=1)
    return cmd_t, cmd_u, st, sy + rng.normal(0.0, noise, sy.shape)


def _stamp(seconds: float) -> Any:
    Time = STORE.types["builtin_interfaces/msg/Time"]
    ns = int(round(seconds * 1e9))
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def joint_state(t: float, names: Sequence[str], pos: Sequence[float], stamp: float | None = None) -> Any:
    T = STORE.types
    header = T["std_msgs/msg/Header"](stamp=_stamp(t if stamp is None else stamp), frame_id="")
    return T["sensor_msgs/msg/JointState"](header=header, name=list(names), position=np.asarray(pos, dtype=np.float64),
                                          velocity=np.zeros(0), effort=np.zeros(0))


def trajectory(names: Sequence[str], points: Sequence[tuple[float, Sequence[float]]]) -> Any:
    T = STORE.types
    Duration = T["builtin_interfaces/msg/Duration"]
    pts = [T["trajectory_msgs/msg/JointTrajectoryPoint"](
        positions=np.asarray(p, dtype=np.float64), velocities=np.zeros(0), accelerations=np.zeros(0),
        effort=np.zeros(0), time_from_start=Duration(sec=int(s), nanosec=int(round((s % 1) * 1e9))))
        for s, p in points]
    header = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id="")  # now
    return T["trajectory_msgs/msg/JointTrajectory"](header=header, joint_names=list(names), points=pts)


def forward(values: Sequence[float]) -> Any:
    T = STORE.types
    layout = T["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
    return T["std_msgs/msg/Float64MultiArray"](layout=layout, data=np.asarray(values, dtype=np.float64))


Message = tuple[str, str, float, Any]  # topic, type, recorded at (s after T0), message


def synthetic_messages(*, kind: str = "trajectory", **kwargs: Any) -> list[Message]:
    cmd_t, cmd_u, st, sy = simulate(**kwargs)
    out: list[Message] = []
    for t, u in zip(cmd_t, cmd_u):
        if kind == "trajectory":
            out.append((TRAJ, "trajectory_msgs/msg/JointTrajectory", t, trajectory(JOINTS, [(0.0, u)])))
        else:
            out.append((FWD, "std_msgs/msg/Float64MultiArray", t, forward(u)))
    names = ("left_finger", *JOINTS[::-1])  # another order, and a joint that is not the arm's
    for t, y in zip(st, sy):
        out.append((STATES, "sensor_msgs/msg/JointState", t, joint_state(T0 + t, names, [0.02, *y[::-1]])))
    return out


def write_bag(path: Path, messages: list[Message], *, storage: StoragePlugin = StoragePlugin.SQLITE3,
              raw: dict[str, bytes] | None = None) -> Path:
    """A ROS 2 bag of ``messages`` (recorded at ``T0 + t``), in time order as a recorder writes them."""
    with Writer(path, version=9, storage_plugin=storage) as writer:
        conns: dict[str, Any] = {}
        for topic, msgtype, t, msg in sorted(messages, key=lambda m: m[2]):
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msgtype, typestore=STORE)
            data = raw[topic] if raw and topic in raw else STORE.serialize_cdr(msg, msgtype)
            writer.write(conns[topic], int(round((T0 + t) * 1e9)), data)
    return path


@pytest.fixture(scope="module")
def good_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_bag(tmp_path_factory.mktemp("bags") / "good", synthetic_messages())


def run(argv: Sequence[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = sysid.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


# -- the fit alone ---------------------------------------------------------------------------------
def _recording(**kwargs: Any) -> Recording:
    cmd_t, cmd_u, st, sy = simulate(**kwargs)
    trace = CommandTrace(cmd_t, tuple(np.zeros(1) for _ in cmd_t), tuple(u[None, :] for u in cmd_u))
    return Recording(JOINTS, st, sy, trace)


def test_fit_recovers_latency_lag_gain_offset() -> None:
    fit = fit_recording(_recording(noise=0.004))
    assert abs(fit.latency - 0.1) <= 0.01
    for j, tau, gain, off in zip(fit.joints, (0.25, 0.2, 0.3, 0.15, 0.25), (1.0, 0.95, 1.0, 1.0, 1.05),
                                 (0.02, -0.01, 0.0, 0.0, 0.0)):
        assert j.identified
        assert abs(j.time_constant - tau) / tau < 0.05, j
        assert abs(j.gain - gain) < 0.02 and abs(j.offset - off) < 0.005, j
        assert 0.003 < j.residual < 0.006  # the noise (0.004) and little more: the free run follows the bag


@pytest.mark.parametrize("latency", [0.0, 0.035, 0.3])
def test_fit_latency_between_grid_steps(latency: float) -> None:
    fit = fit_recording(_recording(latency=latency, noise=0.001, seed=3))
    assert abs(fit.latency - latency) <= 0.004, fit.latency
    assert not fit.latency_at_bound


def test_latency_beyond_the_search_says_so() -> None:
    fit = fit_recording(_recording(latency=0.3, noise=0.001), max_latency=0.2)
    assert fit.latency_at_bound and any("largest searched" in n for n in fit.notes)


def test_velocity_limited_samples_are_left_out() -> None:
    vlim = (0.8, 10.0, 10.0, 10.0, 10.0)  # the waist slews at 0.8 rad/s on most steps
    rec = _recording(vlimit=vlim, amplitude=(0.6, 0.3, 0.3, 0.3, 0.3), noise=0.001)
    fit = fit_recording(rec, velocity_limits=vlim)
    waist = fit.joints[0]
    assert waist.slewing > 100
    assert abs(waist.time_constant - 0.25) / 0.25 < 0.1 and abs(fit.latency - 0.1) <= 0.01
    blind = fit_recording(rec).joints[0]  # the same bag, limits not known: the lag comes out longer
    assert blind.slewing == 0 and blind.residual > waist.residual


def test_droop_is_fitted_apart_from_the_lag() -> None:
    """A joint that settles short of its target on the side it came from (a stiff servo under load)."""
    fit = fit_recording(_recording(droop=0.03, noise=0.004))
    assert abs(fit.latency - 0.1) <= 0.01
    for j, tau in zip(fit.joints, (0.25, 0.2, 0.3, 0.15, 0.25)):
        assert abs(j.droop - 0.03) < 0.004 and abs(j.time_constant - tau) / tau < 0.05, j


def test_a_joint_whose_command_does_not_move_is_not_identified() -> None:
    fit = fit_recording(_recording(amplitude=(0.4, 0.4, 0.4, 0.4, 0.0)))
    still = fit.joints[-1]
    assert not still.identified and still.gain == 1.0 and still.offset == 0.0 and math.isnan(still.residual)
    assert all(j.identified for j in fit.joints[:-1])
    with pytest.raises(FitError, match="no joint's command moved"):
        fit_recording(_recording(amplitude=(0.001,) * 5))


def test_too_little_to_fit() -> None:
    rec = _recording(seconds=1.0)
    with pytest.raises(FitError, match="a fit needs at least"):
        fit_recording(rec)
    empty = Recording(JOINTS, rec.times, rec.positions, CommandTrace(np.zeros(0), (), ()))
    with pytest.raises(FitError):
        fit_recording(Recording(JOINTS, np.arange(500) * 0.01, np.zeros((500, 5)), empty.commands))


def test_setpoints_follow_a_trajectory_controller() -> None:
    """A trajectory moves linearly from the setpoint it finds to its points; a later one takes over."""
    trace = CommandTrace(np.array([0.0, 1.0, 1.5]),
                         (np.zeros(1), np.array([1.0]), np.array([0.5, 1.0])),
                         (np.array([[0.0]]), np.array([[2.0]]), np.array([[0.0], [1.0]])))
    t = np.array([-0.5, 0.0, 0.5, 1.25, 1.5, 1.75, 2.0, 3.0])
    u = setpoints(trace, t)[:, 0]
    # before: nan; 0 held; at 1.25 a quarter of 0 -> 2; at 1.5 the third starts from 1.0 to 0 in 0.5 s, then 1
    np.testing.assert_allclose(u[1:], [0.0, 0.0, 0.5, 1.0, 0.5, 0.0, 1.0])
    assert math.isnan(u[0])


# -- bags --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("storage", [StoragePlugin.SQLITE3, StoragePlugin.MCAP])
def test_read_both_storages(tmp_path: Path, storage: StoragePlugin) -> None:
    bag = write_bag(tmp_path / "bag", synthetic_messages(seconds=8.0, kind="forward"), storage=storage)
    topics = default_topics(NS, "arm_controller", None)
    assert topics == BagTopics(STATES, (TRAJ, FWD))
    rec, summary = read_recording(bag, joints=JOINTS, controller_joints=JOINTS, topics=topics)
    assert summary.storage == ("ROS 2 (MCAP)" if storage == StoragePlugin.MCAP else "ROS 2 (sqlite3)")
    assert summary.states == rec.times.size == 799 and summary.commands == len(rec.commands)
    assert summary.skipped == {} and "header stamps" in summary.time_base
    file = next(p for p in bag.iterdir() if p.suffix in (".db3", ".mcap"))
    again, _ = read_recording(file, joints=JOINTS[:2], controller_joints=JOINTS, topics=topics)  # the file, 2 joints
    np.testing.assert_array_equal(again.positions, rec.positions[:, :2])


def test_read_a_ros1_bag(tmp_path: Path) -> None:
    from rosbags.rosbag1 import Writer as Writer1

    store1 = get_typestore(Stores.ROS1_NOETIC)
    cmd_t, cmd_u, st, sy = simulate(seconds=6.0)
    path = tmp_path / "r1.bag"
    with Writer1(path) as writer:
        cs = writer.add_connection(STATES, "sensor_msgs/msg/JointState", typestore=store1)
        cc = writer.add_connection(FWD, "std_msgs/msg/Float64MultiArray", typestore=store1)
        T = store1.types
        msgs = []
        for t, u in zip(cmd_t, cmd_u):
            m = T["std_msgs/msg/Float64MultiArray"](layout=T["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0),
                                                     data=u)
            msgs.append((t, cc, store1.serialize_ros1(m, "std_msgs/msg/Float64MultiArray")))
        for t, y in zip(st, sy):
            ns = int(round((T0 + t) * 1e9))
            header = T["std_msgs/msg/Header"](seq=0, stamp=T["builtin_interfaces/msg/Time"](
                sec=ns // 10**9, nanosec=ns % 10**9), frame_id="")
            m = T["sensor_msgs/msg/JointState"](header=header, name=list(JOINTS), position=y, velocity=np.zeros(0),
                                                effort=np.zeros(0))
            msgs.append((t, cs, store1.serialize_ros1(m, "sensor_msgs/msg/JointState")))
        for t, conn, data in sorted(msgs, key=lambda m: m[0]):
            writer.write(conn, int(round((T0 + t) * 1e9)), data)
    rec, summary = read_recording(path, joints=JOINTS, controller_joints=JOINTS,
                                  topics=default_topics(NS, "arm_controller", None))
    assert summary.storage == "ROS 1" and rec.times.size == st.size and len(rec.commands) == cmd_t.size


def test_hostile_messages_are_skipped_and_counted(tmp_path: Path) -> None:
    msgs = synthetic_messages(seconds=8.0)
    nan = [0.0, float("nan"), 0.0, 0.0, 0.0]
    extra: list[Message] = [
        (STATES, "sensor_msgs/msg/JointState", 2.001, joint_state(T0 + 2.001, JOINTS, nan)),
        (STATES, "sensor_msgs/msg/JointState", 2.002, joint_state(T0 + 2.002, JOINTS[:3], [0.0] * 3)),
        (STATES, "sensor_msgs/msg/JointState", 2.003, joint_state(T0 + 2.003, ["a", "a", "b", "c", "d"], [0.0] * 5)),
        (STATES, "sensor_msgs/msg/JointState", 3.0051, joint_state(T0 + 2.5, JOINTS, [0.0] * 5)),  # 0.5 s late
        (STATES, "sensor_msgs/msg/JointState", 3.0052, joint_state(T0 + 900.0, JOINTS, [0.0] * 5)),  # another clock
        (TRAJ, "trajectory_msgs/msg/JointTrajectory", 4.0001, trajectory(JOINTS, [(0.5, nan)])),
        (TRAJ, "trajectory_msgs/msg/JointTrajectory", 4.0002, trajectory(JOINTS, [(0.5, [0.0] * 5), (0.2, [0.0] * 5)])),
        (TRAJ, "trajectory_msgs/msg/JointTrajectory", 4.0003, trajectory(JOINTS[1:], [(0.5, [0.0] * 4)])),
        (TRAJ, "trajectory_msgs/msg/JointTrajectory", 4.0004, trajectory(JOINTS, [])),
    ]
    rec, summary = read_recording(write_bag(tmp_path / "bag", msgs + extra), joints=JOINTS, controller_joints=JOINTS,
                                  topics=default_topics(NS, "arm_controller", None))
    assert summary.skipped == {
        "joint states with NaN or infinite positions": 1, "joint states without every arm joint": 1,
        "joint states whose names and positions do not match": 1, "joint states stamped out of order or twice": 1,
        "joint states stamped far from when they were recorded": 1,
        "trajectories with NaN positions or times not increasing from >= 0": 2,
        "trajectories without every arm joint": 1,
        "trajectories with no points, too many, or a joint named twice": 1}
    assert rec.times.size == 799 and np.all(np.diff(rec.times) > 0)
    assert fit_recording(rec).latency == pytest.approx(0.1, abs=0.011)  # the rest still fits


def test_undecodable_and_oversized_messages(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    msgs = synthetic_messages(seconds=5.0, kind="forward")
    short = [(FWD, "std_msgs/msg/Float64MultiArray", 0.5, forward([0.0] * 3))]  # 3 values for 5 joints
    bag = write_bag(tmp_path / "bag", msgs + short)
    topics = default_topics(NS, "arm_controller", None)
    rec, summary = read_recording(bag, joints=JOINTS, controller_joints=JOINTS, topics=topics)
    assert summary.skipped == {"forward commands whose length is not the controller's 5 joints": 1}
    # every joint state replaced by 4 bytes that claim a huge string: none decodes, a one-line refusal
    garbage = write_bag(tmp_path / "garbage", msgs, raw={STATES: b"\x00\x01\x00\x00\xff\xff\xff\x7f"})
    with pytest.raises(BagError, match=r"^0 usable joint states \(skipped: 499 messages that do not decode\)"):
        read_recording(garbage, joints=JOINTS, controller_joints=JOINTS, topics=topics)
    import uniros.sysid_bag

    monkeypatch.setattr(uniros.sysid_bag, "MAX_MESSAGE_BYTES", 64)  # every message too large
    with pytest.raises(BagError, match=r"^0 usable joint states \(skipped: 499 messages over 64 bytes;"):
        read_recording(bag, joints=JOINTS, controller_joints=JOINTS, topics=topics)


def test_bag_refusals(tmp_path: Path, good_bag: Path) -> None:
    topics = default_topics(NS, "arm_controller", None)
    kw: dict[str, Any] = {"joints": JOINTS, "controller_joints": JOINTS}
    with pytest.raises(BagError, match="no such bag"):
        read_recording(tmp_path / "nope", topics=topics, **kw)
    (tmp_path / "notabag").mkdir()
    with pytest.raises(BagError, match="no metadata.yaml"):
        read_recording(tmp_path / "notabag", topics=topics, **kw)
    with pytest.raises(BagError, match=r"no topic /other/joint_states \(the bag has: .*/rx200/joint_states"):
        read_recording(good_bag, topics=BagTopics("/other/joint_states", topics.commands), **kw)
    with pytest.raises(BagError, match="none of the command topics"):
        read_recording(good_bag, topics=BagTopics(STATES, ("/x/commands",)), **kw)
    with pytest.raises(BagError, match="is no arm command"):
        read_recording(good_bag, topics=BagTopics(STATES, (STATES,)), **kw)
    with pytest.raises(BagError, match="more than the 0.0 GiB"):
        read_recording(good_bag, topics=topics, max_bytes=1000, **kw)
    with pytest.raises(BagError, match="2,026 messages on the topics read, more than 100:"):
        read_recording(good_bag, topics=topics, max_messages=100, **kw)
    broken = tmp_path / "broken"
    shutil.copytree(good_bag, broken)
    db = next(broken.glob("*.db3"))
    db.write_bytes(b"not sqlite" * 100)
    with pytest.raises(BagError, match="cannot be read as a bag"):
        read_recording(broken, topics=topics, **kw)


# -- the command -------------------------------------------------------------------------------------
def test_cli_prints_the_section(good_bag: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run([good_bag, "--arm", RX200], capsys)
    assert code == 0, err
    import yaml

    section = yaml.safe_load(out)["dynamics"]
    assert abs(section["latency"] - 0.1) <= 0.01
    assert [round(v, 2) for v in section["time_constant"]] == pytest.approx([0.25, 0.2, 0.3, 0.15, 0.25], abs=0.01)
    assert section["gain"][1] == pytest.approx(0.95, abs=0.02)
    assert section["offset"][0] == pytest.approx(0.02, abs=0.004)
    assert 0.001 < section["fit_residual"] < 0.004 and section["source"].startswith("good (uniros sysid, ")
    assert "latency 0.1" in err and "shoulder" in err and "fit residual" in err  # the table on stderr


def _arm_copy(tmp_path: Path, text: str | None = None) -> Path:
    """A copy of the RX200's arm file (its description is a package:// URI: it loads from anywhere)."""
    arm = tmp_path / "arm.yaml"
    arm.write_bytes((RX200.read_text() if text is None else text).encode())
    return arm


def test_cli_write_adds_then_replaces_the_section(tmp_path: Path, good_bag: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    arm = _arm_copy(tmp_path, RX200.read_text().replace("\n", "\r\n"))  # CRLF kept
    before = arm.read_bytes()
    code, out, err = run([good_bag, "--arm", arm, "--write"], capsys)
    assert code == 0, err
    assert "wrote the dynamics: section" in out and "latency" in out
    after = arm.read_bytes()
    assert after.startswith(before) and after[len(before):].startswith(b"dynamics:") and b"\n" not in after.replace(
        b"\r\n", b"")
    code, _, err = run([good_bag, "--arm", arm, "--write", "--joints", "waist", "elbow"], capsys)  # replaced in place
    assert code == 0, err
    again = arm.read_bytes()
    assert again.count(b"dynamics:") == 1 and again.startswith(before)
    import yaml

    first, second = yaml.safe_load(after)["dynamics"], yaml.safe_load(again)["dynamics"]
    assert second["time_constant"][1] == first["time_constant"][1]  # shoulder: not fitted, kept
    assert "not fitted or not identified" in again.decode()


def test_cli_write_in_the_middle_keeps_every_other_line(tmp_path: Path, good_bag: Path,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    text = RX200.read_text()
    head, tail = text.split("reach:\n", 1)
    old = ("dynamics:\n  latency: 9.0   # old, and out of bounds: replaced\n\n  gain: 1.0\n"
           "# a comment of the next section\n")
    arm = _arm_copy(tmp_path, head + old + "reach:\n" + tail)
    code, _, err = run([good_bag, "--arm", arm, "--write"], capsys)
    assert code == 0, err
    new = arm.read_text()
    assert new.startswith(head + "dynamics:") and new.endswith("\n# a comment of the next section\nreach:\n" + tail)
    assert "9.0" not in new


def test_cli_output_writes_a_copy(tmp_path: Path, good_bag: Path, capsys: pytest.CaptureFixture[str]) -> None:
    arm = _arm_copy(tmp_path)
    digest = hashlib.sha256(arm.read_bytes()).hexdigest()
    code, out, err = run([good_bag, "--arm", arm, "--output", tmp_path / "new.yaml"], capsys)
    assert code == 0, err
    assert hashlib.sha256(arm.read_bytes()).hexdigest() == digest
    assert (tmp_path / "new.yaml").read_text().startswith(arm.read_text())
    code, _, err = run([good_bag, "--arm", arm, "--output", tmp_path / "new.yaml"], capsys)
    assert code == 2 and "exists" in err


def test_write_refused_when_the_file_changed(tmp_path: Path, good_bag: Path, monkeypatch: pytest.MonkeyPatch,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    arm = _arm_copy(tmp_path)
    limits: Callable[..., Any] = sysid._velocity_limits

    def meddle(*args: Any) -> Any:  # someone edits the file while the fit runs
        arm.write_text(arm.read_text() + "# edited\n")
        return limits(*args)

    monkeypatch.setattr(sysid, "_velocity_limits", meddle)
    code, _, err = run([good_bag, "--arm", arm, "--write"], capsys)
    assert code == 2 and "changed since uniros sysid read it" in err
    assert arm.read_text().endswith("# edited\n") and "dynamics" not in arm.read_text()
    assert [p.name for p in tmp_path.iterdir()] == ["arm.yaml"]  # no temporary file left


def test_with_section_refuses_what_a_text_edit_cannot_place() -> None:
    with pytest.raises(sysid.SysidError, match="cannot be placed by a text edit"):
        sysid.with_section("{format: 1, name: X}\n", "dynamics:\n  latency: 0.1\n")
    with pytest.raises(sysid.SysidError, match="2 top-level dynamics: keys"):
        sysid.with_section("a: 1\ndynamics: {}\ndynamics: {}\n", "dynamics:\n  latency: 0.1\n")
    assert sysid.with_section("a: 1", "dynamics:\n  latency: 0.1\n") == "a: 1\ndynamics:\n  latency: 0.1\n"


@pytest.mark.parametrize("argv, message", [
    (["--joints", "waist", "nope"], "name each of the arm's joints"),
    (["--joint-states-topic", "/elsewhere"], "no topic /elsewhere"),
    (["--command-topic", "bad topic"], "must be a ROS topic name"),
    (["--max-latency", "9"], "must be within [0, 5] s"),
])
def test_cli_errors_are_one_line(good_bag: Path, capsys: pytest.CaptureFixture[str], argv: list[str],
                                 message: str) -> None:
    code, out, err = run([good_bag, "--arm", RX200, *argv], capsys)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("uniros sysid: error: ") and message in err


def test_cli_arm_file_errors(tmp_path: Path, good_bag: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run([good_bag, "--arm", tmp_path / "none.yaml"], capsys)
    assert code == 2 and "arm file not found" in err
    (tmp_path / "big.yaml").write_bytes(b"#" * (2 << 20))
    code, _, err = run([good_bag, "--arm", tmp_path / "big.yaml"], capsys)
    assert code == 2 and "no arm file" in err


def test_add_sysid_parser_wires_the_command() -> None:
    import argparse

    parser = argparse.ArgumentParser(prog="uniros")
    sysid.add_sysid_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["sysid", "b", "--arm", "a.yaml", "--write"])
    assert args.func is sysid.cmd_sysid and args.write and args.bag == "b"
