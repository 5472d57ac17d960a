"""The simulation's controllers file of a drafted arm (``uniros arm add``).

The arm's group position controller and the gripper's, with servo gains per joint from
:mod:`rl_environments.arm_gains` (from the joints' effort limits, the worst gravity torque and the
joint-space inertia over random poses, checked by holding two poses in MuJoCo), and the real driver's
trajectory controller declared too, for ``uniros-fake-robot``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from rl_environments.arm_description_tree import Inspection, _limits
from rl_environments.arm_draft import ArmDraft, _r
from rl_environments.arm_gripper import _Gripper


def _controllers(draft: ArmDraft, ins: Inspection, joints: Sequence[str], gripper: _Gripper | None,
                 home: np.ndarray, start: np.ndarray, rng: np.random.Generator) -> None:
    """The simulation's controllers YAML: servo gains per joint, checked by a settle test."""
    from rl_environments.arm_gains import SAG, servo_gains, settle_error

    model = ins.description.spec.copy().compile()
    lower = np.array([max(_limits(ins.tree.joints[j])[0], -math.pi) for j in joints])
    upper = np.array([min(_limits(ins.tree.joints[j])[1], math.pi) for j in joints])
    effort = [ins.tree.efforts.get(j, 0.0) for j in joints]
    servo = servo_gains(model, joints, effort, lower, upper, rng)
    weak = list(servo.weak)
    gains = {j: {"p": _r(p, 1), "d": _r(d, 2)} for j, p, d in zip(joints, servo.p, servo.d)}
    err = settle_error(model, joints, servo, effort, (home, start))
    draft.settle_error = err
    fingers: dict[str, dict[str, float]] = {}
    if gripper is not None:
        f_effort = ins.tree.efforts.get(gripper.joint, 0.0) or 20.0
        prismatic = ins.tree.joints[gripper.joint].type == "prismatic"
        # A squeeze of at most 20 N (or the effort limit) over the full stroke: the shipped grippers'
        # ~25 N; a stiffer one overpowers the second finger's <mimic> and flings the cube.
        stroke = abs(gripper.open - gripper.closed)
        p = float(np.clip(min(f_effort, 20.0 if prismatic else 2.0) / max(stroke, 1e-3), 20.0, 2000.0))
        fingers[gripper.joint] = {"p": _r(p, 1), "d": _r(0.02 * p, 2)}
        if gripper.independent:  # both fingers driven: the second squeezes as hard over its own stroke
            f_p = float(np.clip(p / abs(gripper.mimic), 20.0, 2000.0))
            fingers[gripper.follower] = {"p": _r(f_p, 1), "d": _r(0.02 * f_p, 2)}
    lines = [
        f"# ros2_control controllers of the {draft.name} in simulation (written by uniros arm add).",
        "#",
        "# arm_position_controller: the group position controller the lockstep envs command;",
        "# gripper_position_controller the commanded finger (the second follows its URDF <mimic>). The",
        f"# real driver's trajectory controller ({draft.sections['real']['arm_controller']}) is declared too, for",
        "# uniros-fake-robot; it is not started in simulation.",
        "#",
        "# gains: position-servo stiffness p (N m/rad, N/m) and damping d of the simulation node's joint",
        f"# servos: p = max(worst gravity torque / {SAG} rad, inertia x (2 pi 4 Hz)^2) over 200 random poses,",
        "# capped where a 4 ms step stays stable; d critically damps the largest inertia. Forces are clamped",
        "# to the URDF efforts. The finger's p squeezes with at most 20 N (or its effort) over the full stroke.",
        "# Settle check (gravity compensation off, 1 s at home and at the start pose):",
        f"# largest tracking error {err:.4f} rad.",
    ]
    if weak:
        lines.append(f"# NOTE: the effort limits of {weak} are below their worst gravity torque.")
    arm_ctrl = draft.sections["real"]["arm_controller"]
    doc: dict[str, Any] = {"controller_manager": {"ros__parameters": {
        "update_rate": 500,
        "joint_state_broadcaster": {"type": "joint_state_broadcaster/JointStateBroadcaster"},
        "arm_position_controller": {"type": "position_controllers/JointGroupPositionController"},
    }}}
    cm = doc["controller_manager"]["ros__parameters"]
    if gripper is not None:
        cm["gripper_position_controller"] = {"type": "position_controllers/JointGroupPositionController"}
    if arm_ctrl not in cm:
        cm[arm_ctrl] = {"type": "joint_trajectory_controller/JointTrajectoryController"}
    doc["joint_state_broadcaster"] = {"ros__parameters": {
        "joints": [*joints, *(list(fingers) if gripper else [])]}}
    doc["arm_position_controller"] = {"ros__parameters": {"joints": list(joints), "gains": gains}}
    if arm_ctrl != "arm_position_controller":
        doc[arm_ctrl] = {"ros__parameters": {
            "joints": list(joints), "command_interfaces": ["position"], "state_interfaces": ["position", "velocity"],
            "state_publish_rate": 100.0, "action_monitor_rate": 20.0, "allow_partial_joints_goal": False,
            "gains": gains}}
    if gripper is not None:
        doc["gripper_position_controller"] = {"ros__parameters": {"joints": list(fingers), "gains": fingers}}
    import yaml

    class _NoAliases(yaml.SafeDumper):
        def ignore_aliases(self, data: Any) -> bool:
            return True

    draft.controllers_yaml = "\n".join(lines) + "\n" + yaml.dump(doc, Dumper=_NoAliases, sort_keys=False,
                                                                 default_flow_style=None, width=110)
