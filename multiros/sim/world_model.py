"""How entities become MuJoCo model elements, and the per-entity reads and writes of the physics.

Functions of the :class:`~multiros.sim.world.World` that work on one ``MjSpec``/``MjModel``/``MjData``
and one :class:`~multiros.sim.world_types.EntityRecord`, with no world state of their own:

* spec assembly: the base scene (:func:`base_spec`), attaching and removing an entity
  (:func:`add_to_spec`, :func:`remove_from_spec`), its initial joint positions;
* binding after each compile: the entity's ids and address arrays (:func:`bind_entity_ids`);
* the physics side of a robot: its default servo hardware (:func:`make_hardware`), reading joint
  state into it (:func:`read_state`), writing actuator gains and commands (:func:`write_actuators`),
  and putting an entity back in its spawn state (:func:`apply_initial`).

Collision filtering follows Gazebo's default (``self_collide`` false): robot geoms use
``contype=2, conaffinity=1``, everything else ``contype=1, conaffinity=3``, so robots touch the
floor and objects but not themselves or each other.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

import mujoco
import numpy as np

from multiros.sim.controller_manager import ControllerManager
from multiros.sim.controllers import JointMode, RobotHardware
from multiros.sim.description import RobotDescription
from multiros.sim.errors import EntityError
from multiros.sim.world_types import EntityCategory, EntityRecord, EntityState, WorldOptions, check_vec3

_ROBOT_CONTYPE, _ROBOT_CONAFFINITY = 2, 1
_WORLD_CONTYPE, _WORLD_CONAFFINITY = 1, 3
_SERVO_WN = 50.0  # rad/s: natural frequency of the default position servos (critically damped)
_VELOCITY_GAIN = 1000.0  # 1/s: default velocity servo bandwidth (kv = inertia x this); implicit, so stable
_MJ_FREE = int(mujoco.mjtJoint.mjJNT_FREE)
#: The floor's tiles, edge marks and all, by ``WorldOptions.floor_color``: rendering only.
FLOOR_COLORS: dict[str, tuple[tuple[float, float, float], tuple[float, float, float], tuple[float, float, float]]] = {
    "light": ((0.86, 0.86, 0.87), (0.8, 0.8, 0.82), (0.68, 0.68, 0.7)),
    "dark": ((0.18, 0.18, 0.2), (0.12, 0.12, 0.14), (0.25, 0.25, 0.28)),
}
DEFAULT_CONTROLLERS = {
    "controller_manager": {"ros__parameters": {
        "joint_state_broadcaster": {"type": "joint_state_broadcaster/JointStateBroadcaster"},
        "position_controller": {"type": "position_controllers/JointGroupPositionController"}}},
}
"""Controllers of a robot whose description names no ros2_control YAML."""


def base_spec(opts: WorldOptions) -> mujoco.MjSpec:
    """The empty scene: options, integrator, floor and light (raises ValueError on bad options)."""
    spec = mujoco.MjSpec()
    spec.modelname = "uniros_world"
    spec.compiler.degree = False
    spec.option.timestep = opts.timestep
    spec.option.gravity = list(check_vec3(opts.gravity, "gravity"))
    integrators = {"euler": mujoco.mjtIntegrator.mjINT_EULER, "rk4": mujoco.mjtIntegrator.mjINT_RK4,
                   "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
                   "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST}
    if opts.integrator not in integrators:
        raise ValueError(f"integrator '{opts.integrator}' is not one of {sorted(integrators)}")
    spec.option.integrator = int(integrators[opts.integrator])
    check_floor_color(opts.floor_color)
    # MuJoCo would reset *all* of mjData on a bad state; we restore only the affected entity.
    spec.option.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
    spec.visual.global_.offwidth = 1920
    spec.visual.global_.offheight = 1080
    _add_scenery(spec, opts)
    if opts.floor:
        spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05],
                                material="uniros_floor", contype=_WORLD_CONTYPE,
                                conaffinity=_WORLD_CONAFFINITY)
    return spec


def check_floor_color(value: object) -> str:
    """``value`` if it names one of :data:`FLOOR_COLORS`, else ValueError saying which do."""
    if not isinstance(value, str) or value not in FLOOR_COLORS:
        raise ValueError(f"floor_color must be one of {sorted(FLOOR_COLORS)}, got {value!r}")
    return value


def _add_scenery(spec: mujoco.MjSpec, opts: WorldOptions) -> None:
    """What rendered images show besides the entities, none of it physics: a pale sky, a floor of
    0.5 m grey tiles (light or dark: ``opts.floor_color``), a sun behind the default views' left
    shoulder and a soft headlight."""
    spec.add_texture(name="uniros_sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                     builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, rgb1=[0.96, 0.97, 0.99],
                     rgb2=[0.72, 0.77, 0.84], width=64, height=384)
    if opts.floor:
        rgb1, rgb2, mark = FLOOR_COLORS[opts.floor_color]
        spec.add_texture(name="uniros_floor", type=mujoco.mjtTexture.mjTEXTURE_2D,
                         builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, rgb1=list(rgb1), rgb2=list(rgb2),
                         mark=mujoco.mjtMark.mjMARK_EDGE, markrgb=list(mark), width=256, height=256)
        floor = spec.add_material(name="uniros_floor", texrepeat=[1, 1], texuniform=True, reflectance=0.0)
        floor.textures[int(mujoco.mjtTextureRole.mjTEXROLE_RGB)] = "uniros_floor"
    if opts.lights:
        spec.visual.headlight.ambient = [0.3, 0.3, 0.3]
        spec.visual.headlight.diffuse = [0.35, 0.35, 0.35]
        spec.visual.headlight.specular = [0.1, 0.1, 0.1]
        spec.visual.quality.shadowsize = 4096
        spec.visual.map.shadowclip = 3.0  # the sun's shadow map covers the views' whole floor (no speckles)
        spec.worldbody.add_light(name="sun", pos=[1.0, -1.5, 3.0], dir=[-0.3, 0.45, -0.85],
                                 type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL, diffuse=[0.65, 0.65, 0.65],
                                 specular=[0.2, 0.2, 0.2], castshadow=True)


def initial_joint_positions(name: str, desc: RobotDescription,
                            given: Mapping[str, float] | None) -> dict[str, float]:
    """Spawn joint positions: ``given``, else the ``<ros2_control>`` ``initial_value``, else 0
    clamped into the limits (EntityError for an unknown joint, ValueError outside the limits)."""
    joints = {j.name: j for j in desc.joints}
    out = {}
    for rc in desc.ros2_control:
        if rc.initial_position is not None and rc.name in joints:
            out[rc.name] = rc.initial_position
    for jname, value in (given or {}).items():
        if jname not in joints:
            raise EntityError(f"spawn '{name}': unknown joint '{jname}' in joint_positions; joints are "
                              f"{list(joints)}")
        out[jname] = float(value)
    for jname, value in out.items():
        j = joints[jname]
        if not math.isfinite(value) or (j.limited and not j.lower <= value <= j.upper):
            raise ValueError(f"spawn '{name}': initial position {value} of joint '{jname}' is outside "
                             f"[{j.lower}, {j.upper}]")
    for j in desc.joints:
        if j.name not in out and j.limited and not j.lower <= 0.0 <= j.upper:
            out[j.name] = min(max(0.0, j.lower), j.upper)
    return out


def add_to_spec(spec: mujoco.MjSpec, ent: EntityRecord, gravcomp: bool) -> dict:
    """Attach an entity under its prefix (mocap holder or free joint) with one actuator per
    actuated joint; returns the added elements."""
    desc = ent.desc
    child = desc.spec.copy()
    robot = ent.info.category == EntityCategory.ROBOT
    for geom in child.geoms:
        if geom.contype or geom.conaffinity:
            geom.contype, geom.conaffinity = ((_ROBOT_CONTYPE, _ROBOT_CONAFFINITY) if robot
                                              else (_WORLD_CONTYPE, _WORLD_CONAFFINITY))
    if gravcomp:
        for body in child.bodies:
            if body is not child.worldbody:
                body.gravcomp = 1.0
    src_root = child.worldbody.first_body()
    if ent.floating:
        frame = spec.worldbody.add_frame(pos=ent.spawn_pos, quat=ent.spawn_quat)
        root = frame.attach_body(src_root, ent.prefix, "")
        free = root.add_freejoint(name=ent.prefix + "__free__")
        if desc.free_damping:  # a free body that slows by drag (its MJCF free joint's damping)
            free.damping = [desc.free_damping, 0.0, 0.0]
        holder = root
    else:
        holder = spec.worldbody.add_body(name=ent.name, pos=ent.spawn_pos, quat=ent.spawn_quat, mocap=True)
        holder.add_frame().attach_body(src_root, ent.prefix, "")
    actuators = []
    efforts = {j.name: j.effort for j in desc.joints}
    for jname in ent.actuated:
        act = spec.add_actuator(name=ent.prefix + jname, target=ent.prefix + jname,
                                trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        act.biastype = mujoco.mjtBias.mjBIAS_AFFINE
        act.ctrllimited = int(mujoco.mjtLimited.mjLIMITED_FALSE)
        if efforts.get(jname, 0.0) > 0:
            act.forcelimited = int(mujoco.mjtLimited.mjLIMITED_TRUE)
            act.forcerange = [-efforts[jname], efforts[jname]]
        actuators.append(act)
    return {"holder": holder, "actuators": actuators}


def remove_from_spec(spec: mujoco.MjSpec, ent: EntityRecord, added: dict | None = None) -> None:
    """Delete an entity's bodies, actuators, meshes, materials and textures from the spec.

    The body goes first: MjSpec deletes the actuators of the joints under it with it, in time about
    linear in the entity's size. Deleting ~1,000 actuators one by one first cost 20 s (each deletion
    re-scans the spec: quadratic), under the node's lock. Actuators that remain (a MuJoCo that does
    not cascade, or actuators on other transmissions) are deleted after, newest first.
    """
    holder = spec.body(ent.name) if not ent.floating else spec.body(ent.prefix + ent.desc.body_name(ent.desc.root))
    if holder is not None:
        parent_frame = holder.frame if ent.floating else None
        spec.delete(holder)
        if parent_frame is not None:
            try:
                spec.delete(parent_frame)
            except Exception:  # the frame is deleted with its body in some MuJoCo versions
                pass
    for collection in (spec.actuators, spec.meshes, spec.materials, spec.textures):
        for element in reversed([e for e in collection if e.name.startswith(ent.prefix)]):
            spec.delete(element)


def bind_entity_ids(m: mujoco.MjModel, ent: EntityRecord) -> None:
    """Resolve an entity's root body, mocap/free-joint addresses and index arrays in a new model."""
    if ent.floating:
        ent.root_bid = m.body(ent.prefix + ent.desc.body_name(ent.desc.root)).id
        free = m.body_jntadr[ent.root_bid]
        ent.free_qadr, ent.free_dadr = int(m.jnt_qposadr[free]), int(m.jnt_dofadr[free])
        ent.mocap_id = -1
    else:
        ent.root_bid = m.body(ent.name).id
        ent.mocap_id = int(m.body_mocapid[ent.root_bid])
    ent.body_ids = np.flatnonzero(m.body_rootid == ent.root_bid).astype(np.intp)
    jnts = np.flatnonzero(np.isin(m.jnt_bodyid, ent.body_ids))
    q, dof = [], []
    for j in jnts:
        width = {_MJ_FREE: 7, 1: 4}.get(int(m.jnt_type[j]), 1)
        q.extend(range(m.jnt_qposadr[j], m.jnt_qposadr[j] + width))
        dof.extend(range(m.jnt_dofadr[j], m.jnt_dofadr[j] + {_MJ_FREE: 6, 1: 3}.get(int(m.jnt_type[j]), 1)))
    ent.qpos_idx, ent.dof_idx = np.array(q, dtype=np.intp), np.array(dof, dtype=np.intp)
    names = ent.info.joint_names
    ent.jnt_qadr = np.array([m.jnt_qposadr[m.joint(ent.prefix + n).id] for n in names], dtype=np.intp)
    ent.jnt_dadr = np.array([m.jnt_dofadr[m.joint(ent.prefix + n).id] for n in names], dtype=np.intp)
    ent.act_ids = np.array([m.actuator(ent.prefix + n).id for n in ent.actuated], dtype=np.intp)
    slot = {n: i for i, n in enumerate(names)}
    ent.effort_slot = np.array([slot[n] for n in ent.actuated], dtype=np.intp)
    ent.act_qadr = ent.jnt_qadr[ent.effort_slot] if ent.actuated else np.zeros(0, dtype=np.intp)
    ent.act_dadr = ent.jnt_dadr[ent.effort_slot] if ent.actuated else np.zeros(0, dtype=np.intp)


def apply_initial(m: mujoco.MjModel, d: mujoco.MjData, ent: EntityRecord) -> None:
    """Put an entity in its spawn state (joints at their initial positions, at rest)."""
    d.qpos[ent.qpos_idx] = m.qpos0[ent.qpos_idx]
    d.qvel[ent.dof_idx] = 0.0
    for i, jname in enumerate(ent.info.joint_names):
        if jname in ent.initial_q:
            d.qpos[ent.jnt_qadr[i]] = ent.initial_q[jname]
    if ent.mocap_id >= 0:
        d.mocap_pos[ent.mocap_id] = ent.spawn_pos
        d.mocap_quat[ent.mocap_id] = ent.spawn_quat


def make_hardware(m: mujoco.MjModel, d: mujoco.MjData, ent: EntityRecord) -> RobotHardware:
    """A robot's hardware view with servo gains scaled by its joint-space inertia at the current
    (spawn) pose: critically damped position servos, stiff velocity servos."""
    mujoco.mj_forward(m, d)
    joints = {j.name: j for j in ent.desc.joints}
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, full)
    mass = full[ent.act_dadr, ent.act_dadr]  # joint-space inertia (with armature) at the spawn pose
    lower = np.array([joints[j].lower for j in ent.actuated])
    upper = np.array([joints[j].upper for j in ent.actuated])
    effort = np.array([joints[j].effort for j in ent.actuated])
    velocity = np.array([joints[j].velocity for j in ent.actuated])
    damping = np.array([joints[j].damping for j in ent.actuated])
    kp, kd = mass * _SERVO_WN ** 2, 2.0 * mass * _SERVO_WN
    kv = mass * _VELOCITY_GAIN + 20.0 * damping  # stiff enough to dominate joint damping/friction
    return RobotHardware(ent.actuated, lower, upper, effort, velocity, kp, kd, kv=kv)


def make_controller_manager(m: mujoco.MjModel, d: mujoco.MjData, ent: EntityRecord,
                            config: str | Path | Mapping | None) -> ControllerManager:
    """Give a robot its hardware view (at the current pose) and a controller manager over it (``config``:
    a ros2_control YAML; default the description's, else :data:`DEFAULT_CONTROLLERS`), returned too;
    no controller spawned yet."""
    ent.hw = make_hardware(m, d, ent)
    read_state(d, ent)
    if config is None:
        config = ent.desc.controllers_yaml if ent.desc.controllers_yaml is not None else DEFAULT_CONTROLLERS
    ent.cm = ControllerManager(ent.hw, config)
    return ent.cm


def read_state(d: mujoco.MjData, ent: EntityRecord) -> None:
    """Copy the robot's actuated joint positions, velocities and actuator forces into its hardware."""
    hw = ent.hw
    hw.position[:] = d.qpos[ent.act_qadr]
    hw.velocity[:] = d.qvel[ent.act_dadr]
    hw.effort[:] = d.actuator_force[ent.act_ids]


def write_actuators(m: mujoco.MjModel, d: mujoco.MjData, ent: EntityRecord) -> None:
    """Apply the hardware's joint modes as actuator gains (when changed) and its commands as ``ctrl``."""
    hw = ent.hw
    if hw is None:
        return
    if hw.dirty:
        for i, act in enumerate(ent.act_ids):
            mode = int(hw.mode[i])
            gain, bias = m.actuator_gainprm[act], m.actuator_biasprm[act]
            gain[:] = 0.0
            bias[:] = 0.0
            if mode == int(JointMode.POSITION):
                gain[0], bias[1], bias[2] = hw.kp[i], -hw.kp[i], -hw.kd[i]
            elif mode == int(JointMode.VELOCITY):
                gain[0], bias[2] = hw.kv[i], -hw.kv[i]
            else:
                gain[0] = 1.0
        pos = hw.mode == int(JointMode.POSITION)
        ent.ff_scale = np.where(pos, hw.kd / np.where(hw.kp > 0, hw.kp, 1.0), 0.0)
        hw.dirty = False
    command = hw.command if ent.shaping is None else ent.shaping.shape(hw.command, hw.mode, d.time)
    d.ctrl[ent.act_ids] = command + ent.ff_scale * hw.command_velocity


def hold_here(m: mujoco.MjModel, d: mujoco.MjData, ent: EntityRecord) -> None:
    """After a teleport or reset: the robot's active controllers hold where it is, no command in flight."""
    if ent.cm is None:
        return
    ent.countdown = 0
    read_state(d, ent)
    ent.cm.hold(d.time)
    if ent.shaping is not None:
        ent.shaping.clear()
    write_actuators(m, d, ent)


def root_state(d: mujoco.MjData, ent: EntityRecord) -> EntityState:
    """Root pose and twist of an entity in the world frame (fresh arrays)."""
    if ent.floating:
        a, v = ent.free_qadr, ent.free_dadr
        quat = d.qpos[a + 3:a + 7].copy()
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, quat)
        return EntityState(d.qpos[a:a + 3].copy(), quat, d.qvel[v:v + 3].copy(),
                           rot.reshape(3, 3) @ d.qvel[v + 3:v + 6])
    return EntityState(d.xpos[ent.root_bid].copy(), d.xquat[ent.root_bid].copy(), np.zeros(3), np.zeros(3))


def set_root_state(d: mujoco.MjData, ent: EntityRecord, pos: np.ndarray | None, quat: np.ndarray | None,
                   lin: np.ndarray | None, ang: np.ndarray | None) -> None:
    """Write validated root pose/twist fields (None = unchanged): the free joint of a floating
    entity, the mocap holder of a fixed-base one (ValueError for a non-zero twist). No forward pass."""
    if ent.floating:
        a, v = ent.free_qadr, ent.free_dadr
        if pos is not None:
            d.qpos[a:a + 3] = pos
        if quat is not None:
            d.qpos[a + 3:a + 7] = quat
        if lin is not None:
            d.qvel[v:v + 3] = lin
        if ang is not None:
            rot = np.zeros(9)
            mujoco.mju_quat2Mat(rot, d.qpos[a + 3:a + 7])
            d.qvel[v + 3:v + 6] = rot.reshape(3, 3).T @ ang
    else:
        if (lin is not None and np.any(lin)) or (ang is not None and np.any(ang)):
            raise ValueError(f"entity '{ent.name}' has a fixed base; it cannot be given a non-zero twist")
        if pos is not None:
            d.mocap_pos[ent.mocap_id] = pos
        if quat is not None:
            d.mocap_quat[ent.mocap_id] = quat


def geom_bounds(m: mujoco.MjModel, d: mujoco.MjData, ent: EntityRecord) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned world bounding box ``(lower xyz, upper xyz)`` of an entity's geoms."""
    geoms = np.flatnonzero(np.isin(m.geom_bodyid, ent.body_ids))
    if geoms.size == 0:
        p = d.xpos[ent.root_bid].copy()
        return p, p.copy()
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
    pts = []
    for g in geoms:
        center, half = m.geom_aabb[g, :3], m.geom_aabb[g, 3:]
        local = center + signs * half
        pts.append(d.geom_xpos[g] + local @ d.geom_xmat[g].reshape(3, 3).T)
    allpts = np.vstack(pts)
    return allpts.min(axis=0), allpts.max(axis=0)
