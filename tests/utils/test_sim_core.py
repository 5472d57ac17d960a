"""sim_core / gazebo_core against a fake simulation node served over the in-process ROS transport,
plus (guarded) against the real MuJoCo node."""

from __future__ import annotations

import numpy as np
import pytest

from multiros.ros import Context, Node
from multiros.ros.interfaces import get_message, get_service
from multiros.sim.client import SimulationClient, SimulationServiceError
from multiros.utils import gazebo_core, sim_core

Result = get_message("simulation_interfaces/msg/Result")
SimulationState = get_message("simulation_interfaces/msg/SimulationState")


class FakeSimNode:
    """Serves the services sim_core uses and records the requests."""

    def __init__(self, ctx: Context, name: str = "fake_sim") -> None:
        self.node = Node(name, context=ctx)
        self.calls: list[tuple[str, object]] = []
        self.state = SimulationState.STATE_PAUSED
        self.physics = {"time_step": 0.002, "real_time_factor": 1.0, "gravity": (0.0, 0.0, -9.81)}
        services = (("reset_simulation", "simulation_interfaces"), ("set_simulation_state", "simulation_interfaces"),
                    ("step_simulation", "simulation_interfaces"), ("get_physics_properties", "uniros_interfaces"),
                    ("set_physics_properties", "uniros_interfaces"))
        for srv, pkg in services:
            type_name = "".join(part.capitalize() for part in srv.split("_"))
            self.node.create_service(get_service(f"{pkg}/srv/{type_name}"), f"~/{srv}", getattr(self, "_" + srv))

    def _ok(self, response):
        response.result.result = Result.RESULT_OK
        return response

    def _reset_simulation(self, req, res):
        self.calls.append(("reset", int(req.scope)))
        return self._ok(res)

    def _set_simulation_state(self, req, res):
        self.calls.append(("state", int(req.state.state)))
        if req.state.state == self.state:
            res.result.result = res.ALREADY_IN_TARGET_STATE
            return res
        self.state = req.state.state
        return self._ok(res)

    def _step_simulation(self, req, res):
        self.calls.append(("step", int(req.steps)))
        if self.state != SimulationState.STATE_PAUSED:
            res.result.result = Result.RESULT_OPERATION_FAILED
            res.result.error_message = "simulation is not paused"
            return res
        return self._ok(res)

    def _fill(self, res):
        res.time_step = self.physics["time_step"]
        res.real_time_factor = self.physics["real_time_factor"]
        res.gravity.x, res.gravity.y, res.gravity.z = self.physics["gravity"]
        return self._ok(res)

    def _get_physics_properties(self, req, res):
        return self._fill(res)

    def _set_physics_properties(self, req, res):
        if req.set_time_step:
            self.physics["time_step"] = req.time_step
        if req.set_real_time_factor:
            self.physics["real_time_factor"] = req.real_time_factor
        if req.set_gravity:
            self.physics["gravity"] = (req.gravity.x, req.gravity.y, req.gravity.z)
        return self._fill(res)


@pytest.fixture
def fake():
    ctx = Context(transport="inproc").init()
    sim = FakeSimNode(ctx)
    user = Node("user", context=ctx)
    client = SimulationClient(user, "/fake_sim", timeout_sec=2.0)
    yield sim, client
    client.close()
    ctx.try_shutdown()


def test_pause_unpause(fake):
    sim, client = fake
    sim_core.unpause_sim(client)
    assert sim.state == SimulationState.STATE_PLAYING
    gazebo_core.unpause_gazebo(client)  # already playing is not an error
    gazebo_core.pause_gazebo(client, max_tries=5, ros_port=11311)  # MultiROS keywords are ignored
    assert sim.state == SimulationState.STATE_PAUSED


@pytest.mark.parametrize(("reset_type", "scope"), [("world", 2), ("simulation", 3)])
def test_reset_scopes_keep_spawned_entities(fake, reset_type, scope):
    sim, client = fake
    gazebo_core.reset_gazebo(client, reset_type=reset_type)
    assert sim.calls[-1] == ("reset", scope)
    assert not sim.calls[-1][1] & 4


def test_reset_default_is_multiros_simulation(fake):
    sim, client = fake
    gazebo_core.reset_gazebo(client)
    assert sim.calls[-1] == ("reset", 3)


def test_bad_reset_type(fake):
    with pytest.raises(ValueError, match="reset_type 'everything'"):
        sim_core.reset_sim(fake[1], "everything")


def test_step(fake):
    sim, client = fake
    gazebo_core.gazebo_step(client, steps=20)
    assert sim.calls[-1] == ("step", 20)
    with pytest.raises(ValueError, match="steps must be an integer >= 1"):
        sim_core.step_sim(client, 0)


def test_step_refused_while_playing_raises_with_node_message(fake):
    _, client = fake
    sim_core.unpause_sim(client)
    with pytest.raises(SimulationServiceError, match="not paused"):
        sim_core.step_sim(client, 1)


def test_physics_properties(fake):
    sim, client = fake
    gazebo_core.set_gazebo_time_step(client, 0.001)
    gazebo_core.set_gazebo_max_update_rate(client, 3.0)
    sim_core.set_gravity(client, (0.0, 0.0, -1.62))
    props = sim_core.get_physics_properties(client)
    assert props == {"time_step": 0.001, "real_time_factor": 3.0, "gravity": (0.0, 0.0, -1.62)}
    assert gazebo_core.get_gazebo_max_update_rate(client) == 3.0
    assert sim_core.get_time_step(client) == 0.001
    assert np.allclose(sim_core.get_gravity(client), (0, 0, -1.62))
    gazebo_core.gazebo_set_gravity(client, 0.0, 0.0, -9.81)
    assert sim.physics["gravity"] == (0.0, 0.0, -9.81)
    with pytest.raises(ValueError, match="time_step must be > 0"):
        sim_core.set_time_step(client, 0.0)


def test_the_migration_pages_legacy_names(fake, caplog):
    """The names docs/migration.md maps: FRobs_RL's capitalised ones, MultiROS' gazebo_physics path,
    the defaults of FRobs_RL, and ODE settings (none in MuJoCo: a setter warns, a getter refuses)."""
    from multiros.utils import gazebo_physics

    sim, client = fake
    assert gazebo_core.close_Gazebo is gazebo_core.close_gazebo
    with pytest.raises(TypeError, match="launch_gazebo.*no_such"):  # FRobs_RL's positional order, our checks
        gazebo_core.launch_Gazebo(True, True, False, no_such=1)
    gazebo_core.gazebo_reset_sim(client, retries=5)  # FRobs_RL's keyword, accepted and ignored
    assert gazebo_physics.set_gazebo_time_step is sim_core.set_time_step
    gazebo_physics.set_gazebo_physics_properties(client, time_step=0.004, max_update_rate=2.0, gravity=(0, 0, -1))
    gazebo_core.gazebo_set_default_properties(client)
    assert sim.physics == {"time_step": 0.001, "real_time_factor": 1.0, "gravity": (0.0, 0.0, -9.81)}
    assert np.allclose(gazebo_core.gazebo_get_gravity(client), (0, 0, -9.81))
    before = list(sim.calls), dict(sim.physics)
    gazebo_core.gazebo_set_ODE_physics(client, False, 0, 50, 1.3, 0.0, 0.001, 0.0, 0.0, 0.2, 20)
    assert "no MuJoCo counterpart" in caplog.text and (sim.calls, sim.physics) == before
    with pytest.raises(NotImplementedError, match="get_gazebo_physics_properties"):
        gazebo_physics.get_gazebo_ode_physics(client)

    class Handle:  # what launch_gazebo returns: its client deletes entities
        class client:  # noqa: N801
            deleted: list[str] = []

            @classmethod
            def delete_entity(cls, name: str) -> None:
                cls.deleted.append(name)

    gazebo_core.gazebo_delete_model(Handle(), "box_0", max_tries=5)
    assert Handle.client.deleted == ["box_0"]


def test_no_hidden_global_simulation():
    with pytest.raises(TypeError, match="no global simulation"):
        sim_core.pause_sim(object())
    with pytest.raises(TypeError):
        gazebo_core.pause_gazebo()  # MultiROS' argument-less call must name the missing simulation


def test_unknown_keyword_refused():
    with pytest.raises(TypeError, match="unexpected keyword"):
        gazebo_core.launch_gazebo(gui=False, no_such_option=1)


def test_launch_mode_checked():
    with pytest.raises(ValueError, match="launch mode 'existing'"):
        sim_core.launch_sim("existing")


# -- against the real node ----------------------------------------------------------------------
def _real_node_available() -> bool:
    try:
        handle = sim_core.launch_sim("composed")
    except Exception:
        return False
    handle.close()
    return True


real_node = pytest.mark.skipif(not _real_node_available(), reason="MuJoCo simulation node not runnable yet")


@real_node
def test_launch_composed_and_control_real_node():
    handle = gazebo_core.launch_gazebo(paused=True, timestep=0.001)
    try:
        assert sim_core.get_time_step(handle) == pytest.approx(0.001)
        sim_core.step_sim(handle, 10)
        sim_core.set_real_time_factor(handle, 2.0)
        assert sim_core.get_real_time_factor(handle) == pytest.approx(2.0)
        sim_core.reset_sim(handle, "simulation")
        sim_core.unpause_sim(handle)
        sim_core.pause_sim(handle)
    finally:
        assert gazebo_core.close_gazebo(handle) is True
    gazebo_core.close_gazebo(handle)  # idempotent


@real_node
@pytest.mark.slow
@pytest.mark.multiprocess
def test_launch_child_process_stopped_by_pid():
    import os

    handle = sim_core.launch_sim("process", timeout_sec=60.0)
    pid = handle.pid
    try:
        assert pid is not None and pid != os.getpid()
        sim_core.step_sim(handle, 5)
    finally:
        sim_core.close_sim(handle)
    assert handle.process.poll() is not None
