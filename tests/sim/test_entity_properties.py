"""Entity properties set apart from the description (multiros.sim.entity_properties; domain randomisation
in the node): scales of the spawned values that do not compound, a restore that puts them back, rows kept
across a recompile, command shaping (latency, lag, gain and offset) in simulated time, bad rows refused
with nothing changed, and the ``~/set_entity_properties`` service."""

from __future__ import annotations

import numpy as np
import pytest

from multiros.sim.entity_properties import CommandShaping, PropertyError
from multiros.sim.world import ResetScope

ARM_XACRO = "package://test_arm_description/urdf/arm.urdf.xacro"
BALL = "package://test_arm_description/urdf/ball.xml"
POSITION = np.ones(3, dtype=int)  # JointMode.POSITION for three joints


def _body(world, entity, link):
    return world.model.body(f"{entity}/{link}").id


def test_scales_apply_to_the_spawned_values_and_restore_puts_them_back(make_world):
    world = make_world()
    world.spawn("arm", ARM_XACRO)
    m = world.model
    b = _body(world, "arm", "link2")
    mass, inertia = float(m.body_mass[b]), m.body_inertia[b].copy()
    dof = m.jnt_dofadr[m.joint("arm/joint2").id]
    damping = float(m.dof_damping[dof])
    rows = (["body", "joint"], ["link2", ""], ["mass", "damping"], [1.5, 2.0])
    changed = world.set_entity_properties("arm", *rows)
    assert changed >= 4
    world.set_entity_properties("arm", *rows)  # twice: the same values, not 2.25 times
    assert m.body_mass[b] == pytest.approx(1.5 * mass)
    np.testing.assert_allclose(m.body_inertia[b], 1.5 * inertia)
    assert m.dof_damping[dof] == pytest.approx(2.0 * damping)
    world.set_entity_properties("arm", [], [], [], [], restore=True)
    assert m.body_mass[b] == mass and m.dof_damping[dof] == damping
    np.testing.assert_array_equal(m.body_inertia[b], inertia)


def test_rows_outlive_a_recompile_elsewhere_in_the_world(make_world):
    world = make_world()
    world.spawn("arm", ARM_XACRO)
    b0 = _body(world, "arm", "link2")
    mass = float(world.model.body_mass[b0])
    world.set_entity_properties("arm", ["body"], ["link2"], ["mass"], [0.5])
    world.spawn("ball", BALL, pose=([1.0, 0, 0.5], [1, 0, 0, 0]))  # a recompile: a new model
    assert world.model.body_mass[_body(world, "arm", "link2")] == pytest.approx(0.5 * mass)
    world.delete("ball")
    assert world.model.body_mass[_body(world, "arm", "link2")] == pytest.approx(0.5 * mass)


def test_a_mass_scale_recomputes_the_constants_mujoco_derives_from_masses(make_world):
    """Subtree masses and inverse weights (what sizes every contact's impedance) follow a mass row, its
    restore and a recompile: left at the spawned masses', a push cube of 1.5 times its mass was flung
    metres by its first contact (RX200PushGoalSim-v0 with ``randomization={"object_mass": [1.5, 1.5]}``)."""
    world = make_world()
    world.spawn("ball", BALL, pose=([0.0, 0, 0.5], [1, 0, 0, 0]))
    b = _body(world, "ball", "ball")
    mass = float(world.model.body_mass[b])

    def consistent(scale: float) -> None:
        m = world.model
        assert m.body_mass[b] == pytest.approx(scale * mass)
        assert m.body_subtreemass[b] == pytest.approx(scale * mass)
        assert m.body_invweight0[b][0] == pytest.approx(1.0 / (scale * mass), rel=1e-6)

    consistent(1.0)
    world.set_entity_properties("ball", ["body"], [""], ["mass"], [1.5])
    consistent(1.5)
    world.spawn("ball2", BALL, pose=([1.0, 0, 0.5], [1, 0, 0, 0]))  # a recompile: the row written again
    consistent(1.5)
    world.set_entity_properties("ball", [], [], [], [], restore=True)
    consistent(1.0)


def test_object_friction_and_size(make_world):
    world = make_world()
    world.spawn("ball", BALL, pose=([0.0, 0, 0.5], [1, 0, 0, 0]))
    m = world.model
    geoms = [g for g in range(m.ngeom) if m.body(m.geom_bodyid[g]).name.startswith("ball/")]
    assert geoms
    friction, size = m.geom_friction[geoms[0]].copy(), m.geom_size[geoms[0]].copy()
    world.set_entity_properties("ball", ["geom", "geom"], ["", ""], ["friction", "size"], [0.5, 1.1])
    assert m.geom_friction[geoms[0]][0] == pytest.approx(0.5 * friction[0])
    assert m.geom_friction[geoms[0]][1] == friction[1], "only the sliding friction"
    np.testing.assert_allclose(m.geom_size[geoms[0]], 1.1 * size)


@pytest.mark.parametrize(("rows", "message"), [
    ((["wheel"], [""], ["mass"], [1.0]), "target 'wheel' is not one of"),
    ((["body"], [""], ["colour"], [1.0]), "body has no property 'colour'"),
    ((["body"], ["no_link"], ["mass"], [1.0]), "has no body 'no_link'"),
    ((["body"], [""], ["mass"], [float("nan")]), "outside"),
    ((["body"], [""], ["mass"], [1e6]), "outside"),
    ((["command"], [""], ["latency"], [5.0]), "outside [0, 2]"),
    ((["command"], ["joint9"], ["gain"], [1.0]), "no actuated joint 'joint9'"),
    ((["body", "body"], ["", "no_link"], ["mass", "mass"], [2.0, 1.0]), "has no body 'no_link'"),
    ((["body"], [], ["mass"], [1.0]), "as long as each other"),
])
def test_a_bad_row_is_refused_and_changes_nothing(make_world, rows, message):
    world = make_world()
    world.spawn("arm", ARM_XACRO)
    before = world.model.body_mass.copy()
    with pytest.raises(PropertyError, match=message.replace("[", r"\[").replace("(", r"\(")):
        world.set_entity_properties("arm", *rows)
    np.testing.assert_array_equal(world.model.body_mass, before)


def test_command_shaping_delays_lags_and_offsets_a_position_command() -> None:
    shaping = CommandShaping(3)
    shaping.latency, shaping.time_constant[:] = 0.1, 0.2
    shaping.gain[:], shaping.offset[:] = 1.0, [0.0, -0.03, 0.0]
    zero, step = np.zeros(3), np.array([0.0, 1.0, 0.0])
    out = shaping.shape(zero, POSITION, 0.0)
    np.testing.assert_allclose(out, [0.0, -0.03, 0.0])  # at rest on its offset from the start
    dt, t = 0.002, 0.0
    trace = []
    while t < 1.5:
        t += dt
        trace.append((t, shaping.shape(step, POSITION, t)[1]))
    before = [v for tt, v in trace if tt < 0.1 - 1e-9]
    assert max(abs(v + 0.03) for v in before) < 1e-12, "nothing moves before the latency"
    at = dict((round(tt, 3), v) for tt, v in trace)
    assert at[0.3] == pytest.approx(-0.03 + (1.0) * (1 - np.exp(-1)), abs=0.01), "63 % one time constant later"
    assert trace[-1][1] == pytest.approx(0.97, abs=1e-3), "settles at gain * command + offset"
    velocity_mode = np.array([2, 2, 2])
    np.testing.assert_array_equal(shaping.shape(step, velocity_mode, 1.6), step), "other modes pass unchanged"


def test_shaped_commands_run_in_the_world_and_off_means_untouched(make_world):
    def run(shaped: bool) -> np.ndarray:
        world = make_world()
        world.spawn("arm", ARM_XACRO)
        if shaped:
            world.set_entity_properties("arm", ["command", "command"], ["", "joint2"], ["latency", "offset"],
                                        [0.05, -0.05])
        world.set_command("arm", "arm_controller", [0.2, 0.3, -0.2])
        trace = []
        for _ in range(50):
            world.step(10)
            trace.append(world.joint_state("arm").position.copy())
        return np.array(trace)

    plain, shaped = run(False), run(True)
    moved = [0, 2]  # joint2 starts at its initial_value 0.3, its command
    assert np.min(np.abs(plain[1][moved])) > 0.05, "the unshaped arm moves at once (0.04 s)"
    assert np.max(np.abs(shaped[1][moved])) < 5e-3, "the shaped one waits (0.05 s)"
    assert shaped[-1][1] == pytest.approx(0.25, abs=0.01), "and settles 0.05 rad short on joint2"
    assert shaped[-1][0] == pytest.approx(plain[-1][0], abs=0.005)


def test_a_reset_clears_the_commands_in_flight(make_world):
    world = make_world()
    world.spawn("arm", ARM_XACRO, initial=True)
    world.set_entity_properties("arm", ["command"], [""], ["latency"], [0.5])
    world.set_command("arm", "arm_controller", [0.4, 0.0, 0.0])
    world.step(50)
    world.reset(ResetScope.STATE)
    world.step(400)  # past the old command's due time: it must not arrive
    assert abs(world.joint_state("arm").position[0]) < 1e-3


def test_the_service_sets_rows_and_refuses_bad_ones(index, tmp_path):
    from multiros.ros import Context, Node
    from multiros.sim.client import SimulationClient, SimulationServiceError
    from multiros.sim.node import SimulationNode
    from multiros.sim.world import World, WorldOptions

    ctx = Context(transport="inproc").init()
    world = World(WorldOptions(), package_index=index, mesh_cache=tmp_path / "meshes")
    SimulationNode("mujoco_sim", world=world, context=ctx)
    client = SimulationClient(Node("tester", context=ctx), "/mujoco_sim", timeout_sec=5.0)
    try:
        client.spawn_entity("arm", uri=ARM_XACRO, namespace="/arm")
        b = world.model.body("arm/link2").id
        mass = float(world.model.body_mass[b])
        assert client.set_entity_properties("arm", [("body", "link2", "mass", 2.0)]) == 1
        assert world.model.body_mass[b] == pytest.approx(2.0 * mass)
        with pytest.raises(SimulationServiceError, match="has no body 'nope'") as err:
            client.set_entity_properties("arm", [("body", "nope", "mass", 2.0)])
        assert err.value.code == 101
        with pytest.raises(SimulationServiceError, match="outside"):
            client.set_entity_properties("arm", [("body", "", "mass", -1.0)])
        with pytest.raises(SimulationServiceError):
            client.set_entity_properties("ghost", [("body", "", "mass", 1.0)])
        client.set_entity_properties("arm", [], restore=True)
        assert world.model.body_mass[b] == mass
    finally:
        client.close()
        ctx.try_shutdown()


def test_camera_pose_field_of_view_and_colours(make_world):
    from multiros.sim.view_camera import camera_entity_urdf

    world = make_world()
    world.spawn("arm", ARM_XACRO)
    world.spawn("cam", camera_entity_urdf((0.8, 0.0, 0.6), (0.0, 0.0, 0.2), 64, 48, 45.0, "/cam"))
    m = world.model
    cams = [c for c in range(m.ncam) if m.body(m.cam_bodyid[c]).name.startswith("cam/")]
    assert cams
    c = cams[0]
    pos, fovy = m.cam_pos[c].copy(), float(m.cam_fovy[c])
    world.set_entity_properties("cam", ["camera", "camera", "camera"], ["", "", ""], ["x", "z", "fovy"],
                                [0.05, -0.02, 1.1])
    np.testing.assert_allclose(m.cam_pos[c], pos + [0.05, 0.0, -0.02])
    assert m.cam_fovy[c] == pytest.approx(1.1 * fovy)
    g = [g for g in range(m.ngeom) if m.body(m.geom_bodyid[g]).name.startswith("arm/")][0]
    rgba = m.geom_rgba[g].copy()
    world.set_entity_properties("arm", ["geom"], [""], ["brightness"], [3.0])
    assert np.all(m.geom_rgba[g, :3] <= 1.0) and m.geom_rgba[g, 3] == rgba[3]
    world.set_entity_properties("cam", [], [], [], [], restore=True)
    np.testing.assert_array_equal(m.cam_pos[c], pos)
    with pytest.raises(PropertyError, match="outside"):
        world.set_entity_properties("cam", ["camera"], [""], ["x"], [5.0])


def test_droop_stops_a_joint_short_on_the_side_it_came_from_and_a_small_command_does_not_move_it() -> None:
    shaping = CommandShaping(3)
    shaping.droop[:] = 0.03
    out = shaping.shape(np.zeros(3), POSITION, 0.0)
    np.testing.assert_allclose(out, 0.0)
    up = shaping.shape(np.array([0.5, 0.0, -0.5]), POSITION, 0.01)
    np.testing.assert_allclose(up, [0.47, 0.0, -0.47])  # short, from below and from above
    small = shaping.shape(np.array([0.49, 0.02, -0.49]), POSITION, 0.02)
    np.testing.assert_allclose(small, [0.47, 0.0, -0.47]), "within the droop of where it stands: no motion"
