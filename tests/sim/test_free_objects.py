"""Free-floating objects: MJCF bodies with a free joint (and joint-less URDF links) spawn, fall,
rest, slide and collide; their state is read and written through the free joint."""

from __future__ import annotations

import numpy as np
import pytest

from multiros.ros import Context, Node
from multiros.ros.interfaces import get_message
from multiros.sim.client import SimulationClient, SimulationServiceError
from multiros.sim.description import load_description
from multiros.sim.node import SimulationNode
from multiros.sim.world import EntityCategory, World, WorldOptions

ARM_XACRO = "package://test_arm_description/urdf/arm.urdf.xacro"
FREE_BOX = "package://test_arm_description/urdf/free_box.xml"
HALF = 0.05
BOX_MJCF = f"""<mujoco model="crate">
  <worldbody>
    <body name="crate">
      <freejoint/>
      <geom type="box" size="{HALF} {HALF} {HALF}" mass="0.3" friction="0.8 0.005 0.0001"/>
    </body>
  </worldbody>
</mujoco>"""
CUBE_URDF = f"""<robot name="cube"><link name="cube">
  <inertial><mass value="0.2"/><inertia ixx="3e-4" iyy="3e-4" izz="3e-4" ixy="0" ixz="0" iyz="0"/></inertial>
  <collision><geometry><box size="{2 * HALF} {2 * HALF} {2 * HALF}"/></geometry></collision>
</link></robot>"""


def _steps(world: World, seconds: float) -> int:
    return int(round(seconds / world.timestep))


def test_mjcf_free_joint_is_taken_out_and_recorded(index):
    desc = load_description(BOX_MJCF, index=index)
    assert desc.free_root and desc.root == "crate" and desc.joints == ()
    unnamed = load_description("<mujoco><worldbody><body><freejoint/><geom size='0.1'/></body></worldbody></mujoco>",
                               index=index)
    assert unnamed.free_root and unnamed.root == "base_link"
    assert not load_description(FREE_BOX.replace("free_box", "ball"), index=index).free_root


@pytest.mark.parametrize("source", [BOX_MJCF, CUBE_URDF], ids=["mjcf_free_joint", "urdf_single_link"])
def test_box_falls_and_rests_at_half_height(make_world, source):
    world = make_world()
    info = world.spawn("box", source, pose=([0.1, -0.2, 0.5], [1, 0, 0, 0]))
    assert info.category == EntityCategory.DYNAMIC_OBJECT and not info.fixed_base
    np.testing.assert_allclose(world.get_entity_state("box").position, [0.1, -0.2, 0.5])
    world.step(_steps(world, 0.2))
    falling = world.get_entity_state("box")
    assert falling.position[2] < 0.35 and falling.linear_velocity[2] < -1.0
    world.step(_steps(world, 0.8))  # one second of sim time in all
    rest = world.get_entity_state("box")
    assert rest.position[2] == pytest.approx(HALF, abs=2e-3)
    np.testing.assert_allclose(rest.position[:2], [0.1, -0.2], atol=1e-3)
    assert np.linalg.norm(rest.linear_velocity) < 1e-3 and np.linalg.norm(rest.angular_velocity) < 1e-2


def test_spawn_pose_orientation_goes_into_the_free_joint(make_world):
    world = make_world()
    quat = np.array([np.cos(0.3), 0.0, 0.0, np.sin(0.3)])  # 0.6 rad about z
    world.spawn("box", BOX_MJCF, pose=([0, 0, 0.2], quat))
    state = world.get_entity_state("box")
    np.testing.assert_allclose(state.orientation, quat, atol=1e-12)
    world.step(_steps(world, 1.0))
    state = world.get_entity_state("box")
    assert state.position[2] == pytest.approx(HALF, abs=2e-3)
    np.testing.assert_allclose(np.abs(state.orientation @ quat), 1.0, atol=1e-4)  # landed flat, same yaw


def test_set_entity_state_moves_and_slides_it(make_world):
    world = make_world()
    world.spawn("box", BOX_MJCF, pose=([0, 0, HALF], [1, 0, 0, 0]))
    world.step(_steps(world, 0.2))
    world.set_entity_state("box", position=[1.0, 0.5, 0.3], orientation=[0, 0, 0, 3])
    state = world.get_entity_state("box")
    np.testing.assert_allclose(state.position, [1.0, 0.5, 0.3])
    np.testing.assert_allclose(state.orientation, [0, 0, 0, 1])
    world.step(_steps(world, 0.6))
    assert world.get_entity_state("box").position[2] == pytest.approx(HALF, abs=2e-3)
    start = world.get_entity_state("box").position.copy()
    world.set_entity_state("box", linear_velocity=[1.0, 0, 0], angular_velocity=[0, 0, 0])
    np.testing.assert_allclose(world.get_entity_state("box").linear_velocity, [1.0, 0, 0])
    world.step(_steps(world, 0.5))
    end = world.get_entity_state("box")
    slid = end.position[0] - start[0]
    assert 0.02 < slid < 0.2  # friction 0.8 stops it after about v^2 / (2 mu g) = 6 cm
    assert np.linalg.norm(end.linear_velocity) < 1e-3
    with pytest.raises(ValueError, match="zero"):
        world.set_entity_state("box", orientation=[0, 0, 0, 0])


def test_two_free_objects_collide(make_world):
    world = make_world()
    world.spawn("bottom", BOX_MJCF, pose=([0, 0, HALF], [1, 0, 0, 0]))
    world.spawn("top", FREE_BOX, pose=([0, 0, 0.4], [1, 0, 0, 0]))
    world.step(_steps(world, 1.0))
    assert world.get_entity_state("top").position[2] == pytest.approx(2 * HALF + 0.04, abs=3e-3)  # stacked
    # A box thrown sideways pushes the other one.
    world.set_entity_state("top", position=[-0.3, 0, 0.04], linear_velocity=[3.0, 0, 0])
    before = world.get_entity_state("bottom").position.copy()
    world.step(_steps(world, 0.5))
    assert world.get_entity_state("bottom").position[0] > before[0] + 0.01
    assert world.get_entity_state("top").position[0] < world.get_entity_state("bottom").position[0]


def test_spawn_and_delete_keep_other_free_objects_bit_identical(make_world):
    world = make_world()
    world.spawn("a", BOX_MJCF, pose=([0, 0, 0.5], [1, 0, 0, 0]))
    world.spawn("b", FREE_BOX, pose=([0.5, 0, 0.3], [0.9, 0.1, 0.2, 0.3]))
    world.step(80)  # mid-fall: non-zero velocities

    def snapshot() -> bytes:
        return b"".join(np.concatenate([s.position, s.orientation, s.linear_velocity, s.angular_velocity]).tobytes()
                        for s in (world.get_entity_state("a"), world.get_entity_state("b")))

    before, t = snapshot(), world.time
    world.spawn("c", BOX_MJCF, pose=([-0.5, 0, 0.3], [1, 0, 0, 0]))
    assert snapshot() == before and world.time == t
    world.delete("c")
    assert snapshot() == before and world.time == t


def test_robot_arm_and_free_object_in_one_world(make_world):
    world = make_world()
    world.spawn("arm", ARM_XACRO)
    world.spawn("box", FREE_BOX, pose=([0.3, 0, 0.3], [1, 0, 0, 0]))
    assert world.entity("arm").fixed_base and not world.entity("box").fixed_base
    world.set_command("arm", "", [0.4, 0.2, -0.2])
    world.step(_steps(world, 1.0))
    q = world.joint_state("arm").position
    np.testing.assert_allclose(q, [0.4, 0.2, -0.2], atol=0.03)
    assert world.get_entity_state("box").position[2] == pytest.approx(0.04, abs=2e-3)
    assert world.get_entity_state("arm").position.tolist() == [0.0, 0.0, 0.0]  # the arm's base stays welded


def test_reset_state_puts_a_free_object_back_at_its_spawn_pose(make_world):
    world = make_world()
    world.spawn("box", BOX_MJCF, pose=([0.2, 0, 0.5], [1, 0, 0, 0]), initial=True)
    world.step(_steps(world, 0.5))
    world.reset(2)
    state = world.get_entity_state("box")
    np.testing.assert_allclose(state.position, [0.2, 0, 0.5])
    assert not np.any(state.linear_velocity)


# ---------------------------------------------------------------------------------------- over the node
@pytest.fixture
def sim(index, tmp_path):
    ctx = Context(transport="inproc").init()
    world = World(WorldOptions(), package_index=index, mesh_cache=tmp_path / "meshes")
    SimulationNode("mujoco_sim", world=world, context=ctx)
    client = SimulationClient(Node("tester", context=ctx), "/mujoco_sim", timeout_sec=5.0)
    yield client
    client.close()
    ctx.try_shutdown()


def test_spawn_entity_free_object_as_string_and_package_uri(sim):
    client = sim
    assert client.spawn_entity("crate", resource_string=BOX_MJCF, position=(0, 0, 0.5)) == "crate"
    assert client.spawn_entity("box", uri=FREE_BOX, position=(0.4, 0, 0.3)) == "box"
    EntityCategory_ = get_message("simulation_interfaces/msg/EntityCategory")
    req = client.request("get_entities")
    req.filters.categories = [EntityCategory_(category=EntityCategory_.CATEGORY_DYNAMIC_OBJECT)]
    assert sorted(client._call("get_entities", req).entities) == ["box", "crate"]
    client.step_simulation(500)  # 1 s
    crate = client.get_entity_state("crate")
    assert crate.pose.position.z == pytest.approx(HALF, abs=2e-3)
    assert client.get_entity_state("box").pose.position.z == pytest.approx(0.04, abs=2e-3)
    # SetEntityState: pose and twist go into the free joint.
    req = client.request("set_entity_state", entity="crate")
    for flag in ("set_pose", "set_twist"):  # Rolling's flags; a Jazzy/Kilted request sets everything
        if hasattr(req, flag):
            setattr(req, flag, True)
    req.state.pose.position.x, req.state.pose.position.z = -0.5, 0.3
    req.state.pose.orientation.w = 1.0
    req.state.twist.linear.y = 0.5
    req.state.twist.angular.z = 2.0
    client._call("set_entity_state", req)
    state = client.get_entity_state("crate")
    assert (state.pose.position.x, state.pose.position.z) == (-0.5, 0.3)
    assert (state.twist.linear.y, state.twist.angular.z) == pytest.approx((0.5, 2.0))
    req.state.pose.orientation.w = 0.0  # zero quaternion: refused, state unchanged
    Result = get_message("simulation_interfaces/msg/Result")
    res = client._call("set_entity_state", req)
    assert res.result.result != Result.RESULT_OK and "quaternion" in res.result.error_message.lower()
    assert client.get_entity_state("crate").pose.position.z == 0.3
    client.delete_entity("crate")
    with pytest.raises(SimulationServiceError):
        client.get_entity_state("crate")
    assert client.get_entities() == ["box"]


def test_a_free_joints_damping_is_kept_a_puck_that_glides_and_slows_by_drag(make_world):
    """The world puts its own free joint on a free body; the MJCF's free-joint damping stays on it, so a body
    that glides without friction (condim 1) slows by linear drag: v(t) = v0 exp(-t damping / mass)."""
    puck = ("<mujoco><worldbody><body name='puck'><joint type='free' damping='1.5'/><geom type='box' "
            "size='0.03 0.03 0.015' mass='1' condim='1'/></body></worldbody></mujoco>")
    ice = ("<mujoco><worldbody><body name='ice'><freejoint/><geom type='box' size='2 2 0.05' mass='500' "
           "condim='1'/></body></worldbody></mujoco>")  # frictionless against the puck (the larger condim wins)
    world = make_world()
    world.spawn("ice", ice, pose=([0, 0, 0.05], [1, 0, 0, 0]))
    world.spawn("puck", puck, pose=([0, 0, 0.115], [1, 0, 0, 0]))
    world.step(_steps(world, 0.2))
    world.set_entity_state("puck", linear_velocity=[0.6, 0.3, 0], angular_velocity=[0, 0, 0])
    world.step(_steps(world, 0.4))
    v = world.get_entity_state("puck").linear_velocity
    np.testing.assert_allclose(v[:2], np.array([0.6, 0.3]) * np.exp(-0.4 * 1.5), rtol=0.02)  # straight on
    assert load_description(puck).free_damping == 1.5
    assert load_description(BOX_MJCF).free_damping == 0.0  # a plain free body: no drag
