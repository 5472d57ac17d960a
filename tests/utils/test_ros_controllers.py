"""ros_controllers against a fake controller manager (standard controller_manager_msgs services over
the in-process transport), and (guarded) against the MuJoCo node's controller manager."""

from __future__ import annotations

import pytest

from multiros.ros import Context, Node
from multiros.ros.interfaces import get_message, get_service
from multiros.utils import ros_controllers as rc

ControllerState = get_message("controller_manager_msgs/msg/ControllerState")


class FakeControllerManager:
    def __init__(self, ctx: Context, ns: str) -> None:
        self.node = Node("fake_cm", context=ctx)
        self.states = {"joint_state_broadcaster": "active", "arm_controller": "inactive"}
        self.requests: list[tuple[str, object]] = []
        for name in ("list_controllers", "load_controller", "configure_controller", "switch_controller",
                     "unload_controller"):
            type_name = "".join(p.capitalize() for p in name.split("_"))
            srv = get_service(f"controller_manager_msgs/srv/{type_name}")
            self.node.create_service(srv, f"{ns}/controller_manager/{name}", getattr(self, "_" + name))

    def _list_controllers(self, req, res):
        res.controller = [ControllerState(name=n, state=s, type="fake/Type") for n, s in self.states.items()]
        return res

    def _load_controller(self, req, res):
        self.requests.append(("load", req.name))
        res.ok = req.name not in self.states and not req.name.startswith("bad")
        if res.ok:
            self.states[req.name] = "unconfigured"
        return res

    def _configure_controller(self, req, res):
        self.requests.append(("configure", req.name))
        res.ok = self.states.get(req.name) == "unconfigured"
        if res.ok:
            self.states[req.name] = "inactive"
        return res

    def _switch_controller(self, req, res):
        on, off = list(req.activate_controllers), list(req.deactivate_controllers)
        self.requests.append(("switch", (on, off, int(req.strictness), req.timeout.sec, req.timeout.nanosec)))
        ok = all(self.states.get(n) == "active" for n in off) and all(self.states.get(n) == "inactive" for n in on)
        res.ok = ok
        if ok:
            for n in off:
                self.states[n] = "inactive"
            for n in on:
                self.states[n] = "active"
        return res

    def _unload_controller(self, req, res):
        self.requests.append(("unload", req.name))
        res.ok = self.states.get(req.name) in ("inactive", "unconfigured")
        if res.ok:
            del self.states[req.name]
        return res


@pytest.fixture
def cm():
    ctx = Context(transport="inproc").init()
    fake = FakeControllerManager(ctx, "/robot1")
    user = Node("user", context=ctx)
    yield fake, user
    ctx.try_shutdown()


def test_list(cm):
    fake, node = cm
    infos = rc.list_controllers(node, "/robot1")
    assert {i.name: i.state for i in infos} == fake.states
    assert rc.list_loaded_controllers(node, "robot1") == ["joint_state_broadcaster", "arm_controller"]


def test_spawn_loads_configures_and_activates(cm):
    fake, node = cm
    assert rc.spawn_controllers(node, ["gripper_controller"], ns="/robot1") is True
    assert fake.states["gripper_controller"] == "active"
    assert [r[0] for r in fake.requests] == ["load", "configure", "switch"]


def test_start_stop_and_switch_with_timeout(cm):
    fake, node = cm
    rc.start_controllers(node, ["arm_controller"], ns="/robot1")
    assert fake.states["arm_controller"] == "active"
    rc.stop_controllers(node, ["arm_controller"], ns="/robot1")
    assert fake.states["arm_controller"] == "inactive"
    rc.switch_controllers(node, ["arm_controller"], ["joint_state_broadcaster"], ns="/robot1", strictness=rc.STRICT,
                          timeout=1.25)
    assert fake.requests[-1] == ("switch", (["arm_controller"], ["joint_state_broadcaster"], 2, 1, 250_000_000))
    assert fake.states == {"joint_state_broadcaster": "inactive", "arm_controller": "active"}


def test_reset_stops_then_starts_all_active(cm):
    fake, node = cm
    rc.reset_controllers(node, ns="/robot1")
    switches = [r[1][:2] for r in fake.requests if r[0] == "switch"]
    assert switches == [([], ["joint_state_broadcaster"]), (["joint_state_broadcaster"], [])]
    assert fake.states["joint_state_broadcaster"] == "active"


def test_unspawn(cm):
    fake, node = cm
    rc.kill_controllers_srv(node, ["joint_state_broadcaster"], ns="/robot1")  # FRobs_RL name
    assert "joint_state_broadcaster" not in fake.states


def test_refusal_raises_with_names(cm):
    _, node = cm
    with pytest.raises(rc.ControllerManagerError, match="refused to load controller 'bad_one'"):
        rc.load_ros_controller(node, "bad_one", ns="/robot1")
    with pytest.raises(rc.ControllerManagerError, match="unload controller 'joint_state_broadcaster'"):
        rc.unload_controller_srv(node, "joint_state_broadcaster", ns="/robot1")


def test_missing_manager_times_out_with_namespace(cm):
    _, node = cm
    with pytest.raises(rc.ControllerManagerError, match=r"/nobody/controller_manager/list_controllers within 0.2 s"):
        rc.list_controllers(node, "/nobody", timeout_sec=0.2)


def test_wait_until_ready_answers_times_out_and_sees_the_process_exit(cm):
    import subprocess
    import sys
    import time

    _, node = cm
    rc.ControllerManagerClient(node, "/robot1").wait_until_ready(2.0)  # the fake answers
    started = time.monotonic()
    with pytest.raises(rc.ControllerManagerError,
                       match=r"/nobody did not answer /nobody/controller_manager/list_controllers within 0.3 s"):
        rc.ControllerManagerClient(node, "/nobody").wait_until_ready(0.3)
    assert time.monotonic() - started < 2.0
    proc = subprocess.Popen([sys.executable, "-c", "raise SystemExit(3)"])
    try:
        proc.wait(timeout=30)
        with pytest.raises(rc.ControllerManagerError, match=rf"pid {proc.pid}\) exited with code 3 before"):
            rc.ControllerManagerClient(node, "/nobody").wait_until_ready(30.0, proc)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
    assert not [c for c in node.clients if "nobody" in c.srv_name]  # its probe client is gone


def test_client_object_and_node_of_env_like():
    ctx = Context(transport="inproc").init()
    try:
        FakeControllerManager(ctx, "")

        class EnvLike:
            node = Node("env_node", context=ctx)

        client = rc.ControllerManagerClient(EnvLike(), None)
        assert client.service_name("list_controllers") == "/controller_manager/list_controllers"
        assert client.states()["arm_controller"] == "inactive"
        client.close()
        with pytest.raises(TypeError, match="multiros.ros Node"):
            rc.ControllerManagerClient(object())
    finally:
        ctx.try_shutdown()


# -- against the MuJoCo node ------------------------------------------------------------------------
def _spawned_rx200():
    from multiros.sim.launch import connect

    conn = connect("composed")
    try:
        conn.client.spawn_entity("rx200", uri="package://rx200_description/urdf/rx200.urdf.xacro?robot_name=rx200",
                                 namespace="/rx200", timeout_sec=60.0)
    except BaseException:
        conn.close()
        raise
    return conn


def _node_ready() -> bool:
    try:
        _spawned_rx200().close()
    except Exception:
        return False
    return True


@pytest.mark.skipif(not _node_ready(), reason="MuJoCo simulation node cannot spawn the RX200 yet")
def test_real_controller_manager_reset_and_switch():
    conn = _spawned_rx200()
    try:
        cm = rc.ControllerManagerClient(conn.node, "/rx200")
        states = cm.states()
        assert states.get("joint_state_broadcaster") == "active"
        active = [n for n, s in states.items() if s == "active"]
        assert active
        cm.reset()
        assert {n for n, s in cm.states().items() if s == "active"} == set(active)
        cm.deactivate(active[0])
        assert cm.states()[active[0]] == "inactive"
        cm.activate(active[0])
        assert cm.states()[active[0]] == "active"
        cm.close()
    finally:
        conn.close()
