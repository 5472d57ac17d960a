"""The values of an arm file inferred from an inspected description (``uniros arm add``).

:func:`draft_arm` works out what it can from an :class:`~rl_environments.arm_description_tree.Inspection`,
with a comment on every value it inferred or guessed (an :class:`~rl_environments.arm_draft.ArmDraft`):

* the arm: the longest serial chain of 4 to 7 actuated revolute (or continuous) joints from the
  root, stopping at the first prismatic, mimic or branching joint (the gripper's fingers). Two
  chains of one length (a dual-arm robot): the first in URDF order; the file names the others;
* the gripper and the end effector: :mod:`rl_environments.arm_gripper`;
* the approach axis (the EE frame's axis from the wrist towards the fingers) and the closing axis
  (the fingers' axis, in the EE frame);
* home (zeros clipped into the limits, unless that puts the EE below the base), the workspace
  and reach goal boxes from the forward kinematics of random configurations, the object box where
  :class:`~rl_environments.arm_ik.ChainTopDownIK` reaches the table and the lift height in front of
  the base, a top-down start pose whose joints stay clear of the floor, the table's and the cube's
  sizes from the reach and the gripper's opening (the scene is made from them:
  :mod:`rl_environments.arm_scene`);
* the simulation's controllers: :mod:`rl_environments.arm_sim_controllers`;
* the real twin's driver names: :mod:`rl_environments.arm_driver_names`.
"""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np

from multiros.excerpt import MAX_MESSAGE_LINE, error_line
from rl_environments.arm_description_tree import _MOVING, Inspection, _fail, _limits, _Tree
from rl_environments.arm_draft import ArmDraft, _r, _rl, _rl_within
from rl_environments.arm_driver_names import _real
from rl_environments.arm_gripper import _MIN_OPEN_GAP, _PAD_BACK, _ee_link, _Gripper, _gripper, _Hand
from rl_environments.arm_sim_controllers import _controllers

__all__ = ["draft_arm"]

_CUBE_DENSITY = 1100.0  # kg/m^3: the shipped cubes' (0.14 kg for 5 cm)
_HOLD_ABOVE = 0.02  # m: the EE above a held cube's centre (the scripted grasp: 3 mm; a cube slips ~2 cm in the pads)


def _pick_chain(ins: Inspection) -> tuple[tuple[str, ...], str]:
    tree, chains = ins.tree, ins.chains
    moving = [j for j in tree.robot.joints if j.type in _MOVING and j.mimic is None]
    if not moving:
        _fail(ins.uri, "has no actuated joints; fix: uniros serves serial arms of 4 to 7 revolute joints")
    if all(j.type == "prismatic" for j in moving):
        _fail(ins.uri, f"its actuated joints {[j.name for j in moving]} are all prismatic; fix: uniros serves "
                       "serial arms of 4 to 7 revolute joints (write the arm file by hand for another kind)")
    best = max(chains, key=len) if chains else ()
    if len(best) < 4:
        _fail(ins.uri, f"has no serial chain of 4 to 7 revolute joints from {tree.root!r} (the longest is "
                       f"{list(best)}); fix: uniros serves serial arms of 4 to 7 joints")
    if len(best) > 7:
        _fail(ins.uri, f"its serial chain from {tree.root!r} has {len(best)} revolute joints {list(best)}; fix: "
                       "uniros serves 4 to 7: write the arm file by hand naming 7 of them (docs/add_your_arm.md)")
    others = [c for c in chains if c != best and len(c) >= 4]
    why = f"inferred: the serial chain of {len(best)} revolute joints from {tree.root!r}"
    if others:
        why += (f"; also found {[list(c) for c in others]}: the longest is taken, ties by URDF order "
                "(edit to choose another)")
    return best, why


def _base_link(tree: _Tree, first: str) -> str:
    """The link the arm stands on: up from the first arm joint through fixed joints."""
    link = tree.joints[first].parent
    while link in tree.parent and tree.parent[link].type == "fixed":
        link = tree.parent[link].parent
    return link


def _moving_above(tree: _Tree, link: str) -> list[str]:
    """The moving joints between the root and ``link`` (a torso, a mobile base's): the tasks drive none."""
    found = []
    while link in tree.parent:
        joint = tree.parent[link]
        if joint.type in _MOVING or joint.type in ("floating", "planar"):
            found.append(joint.name)
        link = joint.parent
    return found[::-1]


def _axis_name(vec: np.ndarray, exclude: str | None = None) -> tuple[str, float]:
    order = np.argsort(-np.abs(vec))
    for i in order:
        name = "xyz"[int(i)]
        if name != exclude:
            return name, float(vec[int(i)])
    raise AssertionError("unreachable")


def draft_arm(ins: Inspection, name: str, *, seed: int = 0) -> ArmDraft:
    """Every value of the arm file for ``name`` from an inspected description (see the module docstring)."""
    from multiros.utils.kinematics import KinematicChain
    from rl_environments.arm_ik import ChainTopDownIK

    tree = ins.tree
    draft = ArmDraft(name)
    joints, why_chain = _pick_chain(ins)
    base = _base_link(tree, joints[0])
    moving = _moving_above(tree, base)
    if moving:
        _fail(ins.uri, f"the arm's base {base!r} hangs from moving joint(s) {moving} (a torso, a mobile base) that "
                       "the tasks neither drive nor hold; fix: load the description with the arm on a fixed base "
                       "(its xacro arguments), or write the arm file by hand")
    gripper, why_gripper = _gripper(ins, _Hand(ins), joints[-1])
    if gripper is not None and gripper.pads is not None and gripper.pads[1] < _MIN_OPEN_GAP:
        why_gripper = (f"the open fingers' collision geometry leaves {gripper.pads[1] * 100:.1f} cm between them "
                       "(MuJoCo collides a mesh as its convex hull), too little for the smallest cube (1.6 cm): "
                       "reach only; fix: give the finger links primitive <collision> pads on their inner faces")
        gripper = None
    ee, why_ee, tcp = _ee_link(tree, joints[-1], gripper)
    try:
        chain = KinematicChain.from_urdf(ins.description.text, base, ee, tip_offset=tcp)
    except ValueError as exc:
        _fail(ins.uri, f"the chain {base!r} -> {ee!r}: {error_line(exc, MAX_MESSAGE_LINE)}")
    if tuple(chain.joint_names) != joints:  # a moving joint between the base and the arm: not served
        _fail(ins.uri, f"the moving joints from {base!r} to {ee!r} are {list(chain.joint_names)}, not the arm's "
                       f"{list(joints)}; fix: write the arm file by hand")
    rng = np.random.default_rng(seed)
    n = len(joints)
    lower = np.array([max(_limits(tree.joints[j])[0], -math.pi) for j in joints])
    upper = np.array([min(_limits(tree.joints[j])[1], math.pi) for j in joints])
    wide = [j for j in joints if _limits(tree.joints[j])[0] < -math.pi or _limits(tree.joints[j])[1] > math.pi]

    # Reach: forward kinematics of random configurations.
    qs = rng.uniform(lower, upper, size=(20000, n))
    pts = chain.fk_position(qs)
    radial = np.hypot(pts[:, 0], pts[:, 1])
    reach = float(np.percentile(radial, 99.5))
    if reach < 0.05:
        _fail(ins.uri, f"the arm reaches {reach:.3f} m from its base; fix: check the description's units (metres)")

    # Home: zeros clipped, unless that puts the EE below the base.
    home = np.clip(np.zeros(n), lower, upper)
    why_home = "inferred: zeros clipped into the joint limits (the EE stays above the base)"
    if chain.fk_position(home[None])[0][2] < 0.1 * reach:
        above = qs[pts[:, 2] > 0.3 * reach]
        if len(above):
            home = above[np.argmin(np.linalg.norm(above - home, axis=1))]
        why_home = ("guessed: zeros put the EE below the base, so the sampled pose nearest zeros with the EE "
                    "above it")

    # Axes of the EE frame.
    zero = {j: 0.0 for j in joints}
    if gripper is not None:
        zero[gripper.joint] = gripper.open
        if gripper.independent:
            zero[gripper.follower] = gripper.mimic * gripper.open
    ee_tf = tree.transform(ee, zero)
    wrist = tree.transform(tree.joints[joints[-1]].child, zero)[:3, 3]
    target = gripper.midpoint if gripper is not None else ee_tf[:3, 3]
    out = target - wrist
    k = len(joints) - 2
    while np.linalg.norm(out) < 0.01 and k >= 0:  # the EE at the wrist: from a joint further back
        out = target - tree.transform(tree.joints[joints[k]].child, zero)[:3, 3]
        k -= 1
    approach, sign = _axis_name(ee_tf[:3, :3].T.dot(out))
    why_approach = "inferred: the EE frame's axis from the wrist towards the " + ("fingers" if gripper else "EE")
    if sign < 0:
        why_approach += (f"; it points along -{approach}, and the tasks point +{approach} down: choose an EE link "
                         "whose axis points out of the tool")
    if gripper is not None:
        closing, _ = _axis_name(ee_tf[:3, :3].T.dot(gripper.closing_direction), exclude=approach)
        why_closing = "inferred: the fingers' axis in the EE frame"
    else:
        closing, _ = _axis_name(np.array([1.0, 1.0, 1.0]) * [1, 0.9, 0.8], exclude=approach)
        why_closing = "guessed: no fingers; any axis other than the approach axis"

    # Boxes, in the base frame, scaled by the reach and checked against the samples.
    goal_min = np.array([0.35 * reach, -0.3 * reach, 0.05])
    goal_max = np.array([0.7 * reach, 0.3 * reach, max(0.1, 0.55 * reach)])
    inside = float(np.mean(np.all((pts >= goal_min) & (pts <= goal_max), axis=1)))
    if inside < 0.002:
        _fail(ins.uri, f"random configurations of the chain {list(joints)} reach the goal box {goal_min.round(2)} .. "
                       f"{goal_max.round(2)} in {inside:.2%} of samples; fix: check the joint limits")
    ee_min = [-reach - 0.05, -reach - 0.05, 0.0]
    ee_max = [reach + 0.05, reach + 0.05, float(np.max(pts[:, 2])) + 0.05]
    vel = chain.velocity_limits
    max_vel = float(np.max(vel[np.isfinite(vel)])) if np.any(np.isfinite(vel)) else 6.0
    max_vel = max(max_vel, 1.0)

    # A top-down start pose above the middle of the goal box.
    ik = ChainTopDownIK(chain, approach, closing, home.tolist(), home=home.tolist(), lower=lower.tolist(),
                        upper=upper.tolist())
    start = np.array([0.5 * reach, 0.0, 0.3 * reach])
    base_z = tree.transform(base, {})[2, 3]

    def lowest(q: np.ndarray) -> float:
        values = dict(zip(joints, q))
        return min(tree.transform(tree.joints[j].child, values)[2, 3] for j in joints) - base_z

    seed_q, err = _top_down(ik, chain, start, rng, approach, 0.1 * reach, lowest)
    why_seed = (f"inferred: top-down pose (ChainTopDownIK) with the EE at {_rl(start, 3)} in the base frame"
                if err < 0.005 else f"guessed: the nearest top-down pose found misses {_rl(start, 3)} by "
                f"{err * 100:.1f} cm")

    draft.header = [
        f"{name}: an arm file written by `uniros arm add {ins.uri}`: check every value marked guessed.",
        "An arm file (format 1): see docs/add_your_arm.md for every key.",
        *(f"The description: {note}." for note in tree.robot.notes),
    ]
    draft.sections["format"] = 1
    draft.sections["name"] = name
    draft.sections["robot_name"] = re.sub(r"[^a-z0-9_]", "_", name.lower())
    draft.sections["description"] = {"uri": ins.uri, "xacro_args": dict(ins.xacro_args),
                                     "controllers": f"{name}/controllers.yaml"}
    draft.note("description.controllers", "written by uniros arm add: servo gains from the efforts and masses")
    controllers = ["joint_state_broadcaster", "arm_position_controller"]
    if gripper is not None:
        controllers.append("gripper_position_controller")
    draft.sections["arm"] = {
        "joints": list(joints), "base_link": base, "ee_link": ee, **({"tcp_offset": _rl(tcp)} if np.any(
            np.abs(tcp) > 0) else {}), "home": _rl_within(home, lower, upper),
        "controller": "arm_position_controller", "controllers": controllers,
        "approach_axis": approach, "closing_axis": closing, "ik_seed": _rl_within(seed_q, lower, upper),
    }
    draft.note("arm.joints", why_chain)
    draft.note("arm.base_link", "inferred: the link the first arm joint hangs from (through fixed joints)")
    draft.note("arm.ee_link", why_ee)
    if np.any(np.abs(tcp) > 0):
        draft.note("arm.tcp_offset", f"inferred: between the open fingertips, {_PAD_BACK * 100:g} cm short of their "
                                     "ends (measured on their geometry), in arm.ee_link's frame, metres")
    draft.note("arm.home", why_home)
    draft.note("arm.approach_axis", why_approach)
    draft.note("arm.closing_axis", why_closing)
    draft.note("arm.ik_seed", why_seed)
    if gripper is None:
        draft.sections["gripper"] = None
        draft.note("gripper", why_gripper)
    else:
        draft.sections["gripper"] = {"joints": [gripper.joint, gripper.follower], "mimic": _r(gripper.mimic),
                                     "closed": _r(gripper.closed), "open": _r(gripper.open),
                                     "controller": "gripper_position_controller",
                                     **({"independent": True} if gripper.independent else {})}
        draft.note("gripper", why_gripper)
        draft.note("gripper.open", f"inferred: the other limit; the gap opens by {gripper.opening * 100:.1f} cm")
        if gripper.notes:
            draft.note("gripper.closed", "; ".join(gripper.notes))
    draft.sections["camera"] = {"render_camera": "", "view": {
        "lookat": _rl([0.45 * reach, 0.0, 0.25 * reach], 3), "distance": _r(2.0 * reach + 0.1, 3),
        "azimuth": 140.0, "elevation": -25.0}}
    draft.note("camera.render_camera", "guessed: the description has no camera sensor; renders use the view below")
    limits_why = "inferred: the URDF limits" + (f", {wide} clipped to [-pi, pi] (guessed)" if wide else "")
    draft.sections["reach"] = {
        "min_joint_pos": _rl(lower, 5), "max_joint_pos": _rl(upper, 5),
        "init_joint_pos": _rl_within(seed_q, lower, upper),
        "delta_coeff": 0.05, "ee_delta_coeff": _r(float(np.clip(0.025 * reach / 0.9, 0.015, 0.03)), 3),
        "position_ee_min": _rl(ee_min, 3), "position_ee_max": _rl(ee_max, 3),
        "position_goal_min": _rl(goal_min, 3), "position_goal_max": _rl(goal_max, 3),
        "reach_tolerance": 0.02, "step_reward": -0.5, "multiplier_dist_reward": 2.0, "reached_goal_reward": 20.0,
        "joint_limits_reward": -2.0, "max_joint_vel": _r(max_vel, 3),
    }
    draft.note("reach", f"the reach is {reach:.3f} m (99.5th percentile of the EE's distance from the base axis "
                        "over 20,000 random configurations); the boxes scale with it")
    draft.note("reach.min_joint_pos", limits_why)
    draft.note("reach.init_joint_pos", "inferred: the top-down pose of arm.ik_seed")
    draft.note("reach.position_goal_min", f"inferred: in front of the base; {inside:.1%} of random "
                                          "configurations land in the box")
    draft.note("reach.max_joint_vel", "inferred: the largest URDF velocity limit")

    if gripper is not None:
        init = _manipulation(draft, ik, chain, gripper, reach, lower, upper, seed_q, max_vel, rng)
        if err >= 0.005:  # the first target was out of the top-down IK's reach: the episodes' start is not
            q, err2 = _top_down(ik, chain, init, rng, approach, 0.1 * reach, lowest)
            if err2 < err:
                seed_q, err = q, err2
                ik.seed = ik.home = np.asarray(seed_q)
                draft.sections["arm"]["ik_seed"] = draft.sections["reach"]["init_joint_pos"] = \
                    _rl_within(seed_q, lower, upper)
                draft.note("arm.ik_seed", f"inferred: top-down pose (ChainTopDownIK) with the EE at {_rl(init, 3)} "
                                          "(manipulation.init_ee_position) in the base frame")
    _real(draft, ins, joints, gripper, ee_min, ee_max)
    _controllers(draft, ins, joints, gripper, home, seed_q, rng)
    return draft


def _top_down(ik: Any, chain: Any, target: np.ndarray, rng: np.random.Generator, approach: str, clearance: float,
              lowest: Any = None) -> tuple[np.ndarray, float]:
    """The top-down IK's pose for ``target`` from its seed and random seeds: (q, error). Of the poses
    that meet it, the one whose joints all stay ``clearance`` above the base (``lowest(q)``: the lowest joint's
    height), then the one nearest home; a redundant (7-joint) arm's, the one in its usual posture: each
    pose's redundancy resolved toward home, then the pose whose joints (the tool's roll aside) sit nearest
    the middle of their ranges, not a twisted elbow a random start left."""
    axis = "xyz".index(approach)
    redundant = chain.n_joints > 6
    mid, half = (ik.lower + ik.upper) / 2, np.maximum((ik.upper - ik.lower) / 2, 1e-6)

    def posture(q: np.ndarray) -> float:
        if not redundant:
            return float(np.linalg.norm(q - ik.home))
        away = ((q - mid) / half)[:-1]
        return float(away.dot(away))

    found: list[tuple[float, tuple[bool, float], np.ndarray]] = []
    for s in [None, *chain.sample_configurations(rng, 12)]:
        q = np.asarray(ik.solve(target, q0=s), dtype=float)
        if redundant:  # from there, the redundancy resolved toward home (a seed's null-space pull)
            seed, ik.seed = ik.seed, q
            try:
                q = np.asarray(ik.solve(target), dtype=float)
            finally:
                ik.seed = seed
        tf = chain.fk_matrix(q)
        err = float(np.linalg.norm(tf[:3, 3] - target)) + 0.05 * float(np.linalg.norm(tf[:3, axis] - [0, 0, -1]))
        below = lowest is not None and lowest(q) < clearance
        found.append((err, (below, posture(q)), q))
        if not redundant and sum(f[0] < 0.002 and not f[1][0] for f in found) >= 3:
            break
    good = [f for f in found if f[0] < 0.002]
    err, _, q = min(good, key=lambda f: f[1]) if good else min(found, key=lambda f: f[0])
    return q, err


def _manipulation(draft: ArmDraft, ik: Any, chain: Any, gripper: _Gripper, reach: float, lower: np.ndarray,
                  upper: np.ndarray, seed_q: np.ndarray, max_vel: float, rng: np.random.Generator) -> np.ndarray:
    """The push / pick-and-place settings and scene: a table under the base, a cube the fingers grip;
    returns the start of the episodes (``init_ee_position``), where the top-down IK reaches."""
    gap = gripper.pads[1] if gripper.pads is not None else gripper.opening
    half = float(np.clip(round(0.3 * gap, 3), 0.008, 0.025))
    grips = gripper.pads is None or gripper.pads[0] < 2 * half - 0.004
    robot_height = 0.4 if reach > 0.6 else 0.3
    target_height = _r(0.25 * reach, 3)
    axis = "xyz".index(draft.sections["arm"]["approach_axis"])

    def miss(target: np.ndarray, q0: np.ndarray) -> tuple[float, np.ndarray]:
        q = np.asarray(ik.solve(target, q0=q0), dtype=float)
        tf = chain.fk_matrix(q)
        return float(np.linalg.norm(tf[:3, 3] - target)) + 0.05 * float(np.linalg.norm(tf[:3, axis] - [0, 0, -1])), q

    def carried(height: float) -> float:
        """The EE's height holding the cube at a goal ``height`` above the table: the cube's centre
        (``half`` above the goal's floor) plus where the EE sits on a held cube, slip included."""
        return height + half + _HOLD_ABOVE

    # Along the x axis in front of the base: where the top-down IK reaches the table, and carries the
    # cube to target_height_max (pick-and-place goals in the air).
    x_lo = x_hi = math.nan
    for _ in range(2):
        xs = np.linspace(0.3 * reach, 0.65 * reach, 8)  # not over the base, nor at full stretch (as shipped)
        ok, q_low, q_high = [], seed_q, seed_q
        for x in xs:
            e_low, q_low = miss(np.array([x, 0.0, half + 0.003]), q_low)
            e_high, q_high = miss(np.array([x, 0.0, carried(target_height)]), q_high)
            ok.append(e_low < 0.005 and e_high < 0.005)
            if len(ok) > 1 and ok[-2] and not ok[-1]:
                break  # past the reachable band (it is one band in front of a serial arm)
        runs: list[tuple[int, int]] = []
        for i, good in enumerate(ok):
            if good and (not runs or runs[-1][1] != i - 1):
                runs.append((i, i))
            elif good:
                runs[-1] = (runs[-1][0], i)
        if runs:
            first, last = max(runs, key=lambda r: r[1] - r[0])
            x_lo, x_hi = float(xs[first]), float(xs[last])
            if x_hi - x_lo < 0.04 * reach:  # one sample: a box around it
                x_lo, x_hi = x_lo - 0.02 * reach, x_hi + 0.02 * reach
            break
        target_height = _r(0.5 * target_height, 3)  # the arm may not lift that high top-down
    if math.isnan(x_lo):
        x_lo, x_hi = 0.37 * reach, 0.65 * reach
    # The box lies inside the band's ring: its far corners at radius x_hi, not beyond.
    y_half = min(0.26 * reach, 0.6 * (x_hi - x_lo))
    x_hi = math.sqrt(max(x_hi ** 2 - y_half ** 2, (x_lo + 0.02 * reach) ** 2))
    # Then the corners, narrowing the box's width until the IK reaches them all.
    worst = math.inf
    for _ in range(4):
        corners = [np.array([x, y, z]) for x in (x_lo, x_hi) for y in (-y_half, y_half)
                   for z in (half + 0.003, carried(target_height))]
        worst = max(miss(c, seed_q)[0] for c in corners)
        if worst < 0.01:
            break
        y_half *= 0.6
    why_box = ("inferred: the top-down IK reaches its corners at the table and carrying the cube at target_height_max"
               if worst < 0.01 else
               f"guessed: the top-down IK misses a corner by {worst * 100:.1f} cm; shrink the box")
    init = [_r((x_lo + x_hi) / 2, 3), 0.0, _r(max(0.6 * target_height, min(2 * half + 0.05, target_height)), 3)]
    m: dict[str, Any] = {
        "robot_height": robot_height,
        "table_center": _rl([0.3 * reach, 0.0, -robot_height / 2 - 0.0005], 4),
        "table_half_extents": _rl([0.58 * reach + 0.05, 0.68 * reach + 0.05, robot_height / 2 - 0.0005], 4),
        "table_top": -0.001,
        "object_half_size": half,
        "object_mass": _r(_CUBE_DENSITY * (2 * half) ** 3, 4),
        "init_ee_position": init,
        "object_xy_min": _rl([x_lo, -y_half], 3), "object_xy_max": _rl([x_hi, y_half], 3),
        "goal_xy_min": _rl([x_lo, -y_half], 3), "goal_xy_max": _rl([x_hi, y_half], 3),
        "target_height_max": target_height,
        "position_ee_min": _rl([x_lo - 0.16 * reach, -0.5 * reach, max(0.01, half)], 3),
        "position_ee_max": _rl([x_hi + 0.14 * reach, 0.5 * reach, 2 * target_height], 3),
        "max_object_distance": _r(0.85 * reach, 3),
        "min_joint_pos": _rl(lower, 5), "max_joint_pos": _rl(upper, 5),
        "delta_coeff": 0.05, "ee_delta_coeff": _r(float(np.clip(0.04 * reach / 0.95, 0.015, 0.04)), 3),
        "gripper_min": _r(gripper.closed), "gripper_max": _r(gripper.open),
        "object_yaw_range": 0.3, "target_in_the_air": 0.5,
        "min_object_goal_distance": _r(min(0.08, 0.2 * reach, 0.5 * math.hypot(x_hi - x_lo, 2 * y_half)), 3),
        "distance_threshold": 0.05, "fall_margin": 0.05,
        "max_linear_velocity": 2.0, "max_angular_velocity": 20.0, "max_joint_vel": _r(max_vel, 3),
    }
    draft.sections["manipulation"] = m
    draft.note("manipulation.robot_height", "guessed: the table's height; the base stands on its top")
    what = "gap between the open fingers' geometry" if gripper.pads is not None else "opening"
    draft.note("manipulation.object_half_size", f"inferred: 30 % of the gripper's {gap * 100:.1f} cm {what} "
                                                "(0.8 .. 2.5 cm)" + ("" if grips or gripper.pads is None else
                                                f"; the closed fingers stay {gripper.pads[0] * 100:.1f} cm apart "
                                                "(wider than the cube): guessed, check the grasp"))
    draft.note("manipulation.object_mass", f"inferred: a cube of {_CUBE_DENSITY:g} kg/m^3, as the shipped ones")
    draft.note("manipulation.object_xy_min", why_box)
    draft.note("manipulation.gripper_min", "the closed fingers (gripper.closed)")
    draft.note("manipulation.table_half_extents", "the table and the cube are made from these sizes (no scene: "
                                                  "files to keep in step with them)")
    start = np.array(init)
    return start
