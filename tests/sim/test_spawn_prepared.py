"""A spawn compiled and admitted beside the world (multiros.sim.world_prepare) equals World.spawn at
the time of its commit, bit for bit, and leaves the world untouched when refused or stale."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import mujoco
import numpy as np
import pytest

from multiros.ros import Context, Node
from multiros.sim.client import SimulationClient
from multiros.sim.errors import DescriptionError, SpawnRefusedError

# tests/sim/data's packages (as tests/sim/conftest.py's index finds them); not imported from conftest,
# which another directory's conftest shadows when pytest collects both
DATA = Path(__file__).parent / "data"
ARM_XACRO = "package://test_arm_description/urdf/arm.urdf.xacro"
BALL = "package://test_arm_description/urdf/ball.xml"

BOX = ('<mujoco><worldbody><body name="box"><freejoint/><geom type="box" size="0.05 0.05 0.05" '
       'mass="{m}"/></body></worldbody></mujoco>')
_STATE = int(mujoco.mjtState.mjSTATE_INTEGRATION)


def _state(world) -> np.ndarray:
    m, d = world.model, world.data
    out = np.empty(mujoco.mj_stateSize(m, _STATE))
    mujoco.mj_getState(m, d, out, _STATE)
    return out


def _two_arms(make_world):
    """A world with two arms moving under commands (the same history each call)."""
    world = make_world()
    world.spawn("a", ARM_XACRO)
    world.spawn("b", ARM_XACRO, pose=([1.0, 0, 0], [1, 0, 0, 0]))
    world.set_command("a", "", [0.4, -0.3, 0.2])
    world.set_command("b", "", [-0.2, 0.5, 0.1])
    world.step(40)
    return world


def _prepared_spawn(world, name, description, steps_between=0, **kwargs):
    snapshot = world.spawn_snapshot(name)
    world.step(steps_between)  # the others go on while the newcomer compiles
    prepared = world.prepare_spawn(snapshot, description, **kwargs)
    assert prepared is not None
    return world.commit_spawn(prepared)


@pytest.mark.parametrize("steps_between", [0, 25])
@pytest.mark.parametrize(("name", "description", "position"),
                         [("ball", BALL, [0.5, 0.5, 0.5]), ("arm3", ARM_XACRO, [2.0, 0, 0])])
def test_a_prepared_spawn_equals_a_locked_spawn_at_the_commit(make_world, steps_between, name, description,
                                                              position):
    locked, prepared = _two_arms(make_world), _two_arms(make_world)
    pose = (position, [1, 0, 0, 0])
    locked.step(steps_between)
    locked.spawn(name, description, pose=pose)
    locked.admit(name)
    info = _prepared_spawn(prepared, name, description, steps_between, pose=pose)
    assert info == locked.entity(name)
    assert prepared.entity_names() == locked.entity_names()
    np.testing.assert_array_equal(_state(prepared), _state(locked))
    for world in (locked, prepared):  # and they stay equal: same model, gains and controllers
        world.set_command("a", "", [-0.1, 0.2, 0.3])
        if name == "arm3":
            world.set_command(name, "", [0.3, 0.3, -0.3])
        world.step(60)
    np.testing.assert_array_equal(_state(prepared), _state(locked))
    np.testing.assert_array_equal(prepared.joint_state("b").position, locked.joint_state("b").position)


def test_a_refused_or_broken_spawn_leaves_the_world_as_it_was(make_world):
    world = _two_arms(make_world)
    before, names = _state(world), world.entity_names()
    snapshot = world.spawn_snapshot("through")
    with pytest.raises(SpawnRefusedError) as refused:  # a box spawned through arm a's links
        world.prepare_spawn(snapshot, BOX.format(m=1), pose=([0.03, 0, 0.25], [1, 0, 0, 0]))
    assert refused.value.reason == "overlap"
    broken = '<mujoco><worldbody><body name="x"><geom type="mesh" mesh="nowhere"/></body></worldbody></mujoco>'
    with pytest.raises(DescriptionError):
        world.prepare_spawn(world.spawn_snapshot("broken"), broken)
    assert world.entity_names() == names
    np.testing.assert_array_equal(_state(world), before)
    world.step(5)  # and it steps on


@pytest.mark.parametrize("change", ["spawn", "delete", "timestep", "gravity"])
def test_a_commit_after_the_world_changed_structure_is_refused_untouched(make_world, change):
    world = _two_arms(make_world)
    snapshot = world.spawn_snapshot("ball")
    prepared = world.prepare_spawn(snapshot, BALL, pose=([0.5, 0.5, 0.5], [1, 0, 0, 0]))
    if change == "spawn":
        world.spawn("other", BALL, pose=([0.5, -0.5, 0.5], [1, 0, 0, 0]))
    elif change == "delete":
        world.delete("b")
    elif change == "timestep":
        world.timestep = world.timestep / 2
    else:
        world.gravity = [0.0, 0.0, -1.0]
    before, names = _state(world), world.entity_names()
    assert world.commit_spawn(prepared) is None
    assert world.entity_names() == names and not world.has_entity("ball")
    np.testing.assert_array_equal(_state(world), before)
    world.spawn("ball", BALL, pose=([0.5, 0.5, 0.5], [1, 0, 0, 0]))  # the locked spawn still works


def test_a_name_taken_by_the_snapshot_is_refused_at_once(make_world):
    from multiros.sim.errors import EntityError

    world = _two_arms(make_world)
    with pytest.raises(EntityError, match="already exists"):
        world.spawn_snapshot("a")
    with pytest.raises(EntityError, match="invalid"):
        world.spawn_snapshot("1bad")


@pytest.fixture
def node_and_clients(tmp_path):
    """A simulation node on an in-process graph, and a maker of its clients (each a node of its own)."""
    from multiros.sim.node import SimulationNode
    from multiros.sim.packages import PackageIndex
    from multiros.sim.world import World, WorldOptions

    ctx = Context(transport="inproc").init()
    try:
        world = World(WorldOptions(), package_index=PackageIndex([DATA], use_entry_points=False, environ={}),
                      mesh_cache=tmp_path / "meshes")
        node = SimulationNode("mujoco_sim", world=world, context=ctx, spin_topics=False)
        yield node, lambda name: SimulationClient(Node(name, context=ctx), "/mujoco_sim", timeout_sec=60.0)
    finally:
        ctx.try_shutdown()


def test_the_node_compiles_and_admits_a_spawn_without_holding_its_lock(node_and_clients):
    """A client's step is served while another client's spawn is being compiled and admitted; the
    spawn then lands, and one that a neighbour's spawn overtook lands too (under the lock)."""
    node, client = node_and_clients
    world = node.world
    spawner, stepper = client("a"), client("b")
    stepper.spawn_entity("arm", uri=ARM_XACRO + "?__controllers=joint_state_broadcaster")
    preparing, stepped = threading.Event(), threading.Event()
    prepare = world.prepare_spawn

    def held_prepare(*args, **kwargs):
        preparing.set()
        assert stepped.wait(30.0), "the other client's step was not served during the compile"
        return prepare(*args, **kwargs)

    world.prepare_spawn = held_prepare  # type: ignore[method-assign]
    box = BOX.format(m=0.1)
    result: list[object] = []
    thread = threading.Thread(target=lambda: result.append(
        spawner.spawn_entity("box", resource_string=box, position=(3.0, 0.0, 0.05))))
    thread.start()
    try:
        assert preparing.wait(30.0)
        before = world.time
        stepper.step_simulation(10)  # the node's lock is free while the box compiles
        assert world.time > before
    finally:
        stepped.set()
        thread.join(60.0)
    assert result == ["box"] and world.has_entity("box")

    def overtaken(*args, **kwargs):  # a neighbour's spawn lands first: this one is spawned under the lock
        prepared = prepare(*args, **kwargs)
        with node.lock:
            world.spawn("neighbour", box, pose=([3.0, 1.0, 0.05], [1, 0, 0, 0]))
        return prepared

    world.prepare_spawn = overtaken  # type: ignore[method-assign]
    assert spawner.spawn_entity("late", resource_string=box, position=(3.0, 2.0, 0.05)) == "late"
    assert {"box", "neighbour", "late"} <= set(world.entity_names())
    stepper.step_simulation(5)


def test_concurrent_spawns_all_land_while_a_robot_steps(node_and_clients):
    """Two clients spawn five boxes each at once while a third steps its arm: every spawn lands (a
    commit that another overtook is spawned under the lock), each box where it was asked for, and the
    arm's state goes on from where it was (never back to a snapshot's)."""
    node, client = node_and_clients
    clients = [client(n) for n in ("a", "b", "c")]
    clients[2].spawn_entity("arm", uri=ARM_XACRO)
    box = BOX.format(m=0.1)
    errors: list[BaseException] = []
    spawning = [True, True]
    times: list[float] = []

    def spawn(k: int) -> None:
        try:
            for i in range(5):
                clients[k].spawn_entity(f"box{k}_{i}", resource_string=box, position=(3.0 + i, k, 0.05))
        except BaseException as exc:  # noqa: BLE001 - reported below
            errors.append(exc)
        finally:
            spawning[k] = False

    threads = [threading.Thread(target=spawn, args=(k,)) for k in (0, 1)]
    for thread in threads:
        thread.start()
    deadline = time.monotonic() + 300.0  # ten spawns take a few seconds; a busy machine gets plenty more
    while any(spawning):
        assert time.monotonic() < deadline, "the spawns did not finish within 300 s"
        clients[2].step_simulation(5)
        times.append(node.world.time)
    for thread in threads:
        thread.join(60.0)
    assert not errors, errors
    assert times == sorted(times)  # time only goes on
    for k in (0, 1):
        for i in range(5):
            pos = clients[2].get_entity_state(f"box{k}_{i}").pose.position
            assert abs(pos.x - (3.0 + i)) < 1e-3 and abs(pos.y - k) < 1e-3 and 0.04 < pos.z < 0.06
    clients[2].step_simulation(5)
