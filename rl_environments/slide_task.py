"""Slide, for every arm (Fetch's ``FetchSlide`` on your arm): strike a puck on a low-friction table so that
it slides to a goal beyond the arm's reach. No gripper is needed (an arm with one holds it closed), so the
gripperless IRB120 slides too.

## Scene
The arm stands at the end of a long table whose top is at its base, with a puck on it: a square of 6 cm, 3 cm
high, 1 kg (:data:`PUCK`; square, so that a flat face meets the tool). Table and puck touch without friction,
and the puck slows by linear drag (its free joint's damping, a time constant of 0.67 s: let go at 0.63 m/s, it
glides 0.42 m). Everything is sized from the arm file's ``reach`` goal box (every arm file has one; base
frame): the puck starts a quarter to nearly half way into it, the goal lies 8 to 22 cm past its far edge, out
along the ray from the base through the puck, where the end effector never goes (its box ends at the goal box's
far edge), so the puck must be let go at the right speed.

## Action space
``Box(-1, 1, (3,))``: end-effector deltas ``action * ee_delta_coeff`` (2.5 cm per 40 ms step) in the base
frame, the tool kept pointing down by the arm's top-down IK, targets clipped into the end-effector box (a
few centimetres above the table: low enough to strike the puck).

## Observation space
Goal envs: ``Dict(observation=Box(21 + n), achieved_goal=Box(3), desired_goal=Box(3))``. ``observation``:
EE position, puck position, puck minus EE, puck roll/pitch/yaw, puck linear and angular velocity, EE
velocity, the n arm joints (Fetch's observation without the fingers). ``achieved_goal`` is the puck's
position, ``desired_goal`` the goal. Plain envs: ``Box(27 + n)``, the same values, the goal, and goal minus
puck. World frame; velocities are finite differences over the step; values clipped into the bounds.

## Rewards
``reward_type="sparse"`` (goal envs' default): 0 when the puck is within ``distance_threshold`` (5 cm,
Fetch's) of the goal, else -1; ``"dense"`` (plain envs' default): ``-distance(puck, goal)``; vectorised for HER.

## Episode end
50 steps of 40 ms, truncated; success does not end the episode (``terminate_on_success=False``). A puck
that falls off the table, or slides farther than ``max_object_distance`` from the base, truncates it
(``info["truncated_reason"]``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces

from multiros.robot_state import RobotStates
from rl_environments.arm import Arm
from rl_environments.arm_task import TaskHost, TaskOptions, rows
from rl_environments.manipulation import ObjectGoalSampler, quat_to_euler, yaw_quat
from rl_environments.manipulation_task import ManipulationOptions, ObjectTask

__all__ = ["PUCK", "ScriptedSlide", "SlideOptions", "SlideTask", "slide_config"]

#: The puck and the table it slides on (metres, kilograms; friction of both surfaces).
#: The puck: a square of 2 * ``radius``, ``2 * half_height`` high; it glides on the table without friction and
#: slows by linear drag (its free joint's ``damping``): a puck let go at ``v`` stops ``v * mass / damping`` on.
#: (Coulomb friction would not do: MuJoCo's pyramidal friction cone, the node's, slows a slide along the
#: world's axes one after the other, so the puck would curve.)
PUCK = {"radius": 0.03, "half_height": 0.015, "mass": 1.0, "damping": 1.5}


def slide_config(arm: Arm) -> dict[str, Any]:
    """The slide's scene and settings for ``arm``, from its file's reach section (base frame, metres)."""
    reach = arm.task_config("reach")
    lo, hi = np.asarray(reach["position_goal_min"], float), np.asarray(reach["position_goal_max"], float)
    near, far, width = float(lo[0]), float(hi[0]), float(max(-lo[1], hi[1]))
    top, h = -0.001, PUCK["half_height"]
    height = 0.4  # the base (and the table top) above the floor
    x0, x1 = near - 0.25, far + 0.6
    return {
        "robot_height": height, "table_top": top,
        "table_center": [(x0 + x1) / 2, 0.0, top - (height + top) / 2],
        "table_half_extents": [(x1 - x0) / 2, width + 0.25, (height + top) / 2],
        "object_xy_min": [near + 0.25 * (far - near), -0.5 * width],
        "object_xy_max": [near + 0.45 * (far - near), 0.5 * width],
        "goal_xy_min": [far + 0.08, -0.5 * width], "goal_xy_max": [far + 0.22, 0.5 * width],
        "position_ee_min": [near - 0.1, -width - 0.05, top + h + 0.008],
        "position_ee_max": [far, width + 0.05, top + h + 0.1],
        "init_ee_position": [near + 0.25 * (far - near) - 0.08, 0.0, top + h + 0.03],
        "min_joint_pos": list(reach["min_joint_pos"]), "max_joint_pos": list(reach["max_joint_pos"]),
        "goal_spread": 0.0, "ee_delta_coeff": 0.025, "distance_threshold": 0.05, "min_object_goal_distance": 0.1,
        "fall_margin": 0.05, "max_object_distance": far + 0.65, "max_linear_velocity": 2.0,
        "max_angular_velocity": 20.0,
    }


def _free_body(robot_name: str, item: str, body: str, joint: str, geom: str) -> str:
    return (f'<mujoco model="{robot_name}_slide_{item}"><worldbody><body name="{body}">{joint}'
            f'<geom name="{item}" {geom}/></body></worldbody></mujoco>\n')


@dataclasses.dataclass(frozen=True)
class SlideOptions(ManipulationOptions):
    """The slide's keyword arguments: ``reward_type``, ``distance_threshold`` (success distance, default 5 cm)
    and ``terminate_on_success``. Actions are end-effector deltas (``ee_action_type`` must stay True)."""


class SlideTask(ObjectTask):
    """Strike a puck so that it slides to a goal beyond the arm's reach (see the module docstring)."""

    NAME = "slide"
    OPTIONS = SlideOptions
    options: SlideOptions

    @classmethod
    def load_config(cls, arm: Arm, options: TaskOptions) -> dict[str, Any]:
        if options.config_file is not None or not options.ee_action_type:
            raise ValueError("slide takes its scene from the arm file's reach box and end-effector actions: "
                             "config_file and ee_action_type=False do not apply")
        return slide_config(arm)

    def __init__(self, host: TaskHost, arm: Arm, options: SlideOptions, cfg: Mapping[str, Any], *,
                 goal_conditioned: bool) -> None:
        super().__init__(host, arm, options, cfg, goal_conditioned=goal_conditioned)
        cfg = self.cfg
        self.setup_tool()
        base = self.base_position
        self.half = PUCK["radius"]  # the goal marker: the puck's size
        rest_z = float(cfg["table_top"]) + PUCK["half_height"]
        self.sampler = ObjectGoalSampler(tuple(cfg["object_xy_min"]), tuple(cfg["object_xy_max"]),
                                         tuple(cfg["goal_xy_min"]), tuple(cfg["goal_xy_max"]), rest_z,
                                         min_distance=float(cfg["min_object_goal_distance"]), yaw_range=0.05)
        self.init_joint_pos = self.ik.solve(np.asarray(cfg["init_ee_position"], dtype=np.float64))
        self.action_space = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        self.prev_action = np.zeros(3)
        self.goal = np.array([*self.sampler.goal_low, rest_z]) + base
        gripper = arm.file.gripper
        if gripper is not None and gripper.controller:  # held closed: the fingers strike as one
            self.connection.use_gripper(gripper.controller, (gripper.closed, gripper.open))
        self.add_scene(rest_z, self.sampler.object_low, self.scene_mjcf())
        self.joint_targets = self.init_joint_pos.copy()
        # goals lie on the table, out along rays through the puck's start box
        ray = math.atan2(cfg["object_xy_max"][1], cfg["object_xy_min"][0])
        reach = math.hypot(*cfg["goal_xy_max"]) + 0.01
        low_x = cfg["goal_xy_min"][0] * math.cos(ray) - 0.01
        side = reach * math.sin(ray) + 0.01
        self.goal_low = np.array([low_x, -side, rest_z - 0.001]) + base
        self.goal_high = np.array([reach, side, rest_z + 0.001]) + base
        self.observation_space = self.object_spaces(*self.observation_bounds())

    def scene_mjcf(self) -> tuple[str, str]:
        """The long table and the puck, as MJCF: frictionless contacts between them (``condim="1"``)."""
        name = self.arm.robot_name
        size = " ".join(f"{v:g}" for v in self.cfg["table_half_extents"])
        table = _free_body(name, "table", "table", "<freejoint/>",
                           f'type="box" size="{size}" mass="80" condim="1" rgba="0.45 0.55 0.7 1"')
        r, h = PUCK["radius"], PUCK["half_height"]  # square: a flat face meets the tool (a disc's edge wedges in)
        puck = _free_body(name, "puck", "object", f'<joint type="free" damping="{PUCK["damping"]:g}"/>',
                          f'type="box" size="{r:g} {r:g} {h:g}" mass="{PUCK["mass"]:g}" condim="1" '
                          'solref="0.01 3" rgba="0.1 0.1 0.1 1"')  # overdamped: a strike pushes, not bounces
        return table, puck

    # -- the episode ------------------------------------------------------------------------------------
    def reset_pose(self) -> None:
        self.connection.move_to_initial_pose(self.arm.joints, self.init_joint_pos)
        gripper = self.arm.file.gripper
        if gripper is not None and gripper.controller:
            self.arm.open_gripper_at_reset(self.connection, gripper.closed)
            self.arm.command_gripper(self.connection, gripper.closed)
        self.joint_targets = self.init_joint_pos.copy()

    def start_episode(self, rng: np.random.Generator) -> None:
        base = self.base_position
        obj, yaw, goal = self.sampler.sample(rng)
        # the goal out along the ray from the base through the puck (within goal_spread): the tool, which
        # points down with its fingers across that ray, strikes the puck's face square
        ray = math.atan2(obj[1], obj[0]) + rng.uniform(-1.0, 1.0) * float(self.cfg["goal_spread"])
        out = math.hypot(goal[0], goal[1]) - math.hypot(obj[0], obj[1])
        goal[:2] = obj[:2] + out * np.array([math.cos(ray), math.sin(ray)])
        self.goal = goal + base
        self.place_object(obj + base, yaw_quat(yaw))
        self.prev_action = np.zeros(3)
        self.ee_goal = np.full(3, np.nan)  # the first action moves from where the arm is
        self._episode_start = True
        self.show_object_goal()

    # -- the step, rows of a batch --------------------------------------------------------------------------
    @classmethod
    def act(cls, tasks: Sequence[SlideTask], actions: np.ndarray, states: RobotStates) -> None:
        """End-effector targets through each env's top-down IK, clipped into its box and joint range."""
        arm = tasks[0].arm
        current = arm.positions_of(states)
        goals = cls.ee_goals(tasks, arm.ee_positions_of(tasks[0].connection, states), actions)
        if all(task.ik_key == tasks[0].ik_key for task in tasks):
            targets = tasks[0].ik.solve_rows(goals, q0=current)
        else:
            targets = np.array([task.ik.solve(goals[j], q0=current[j]) for j, task in enumerate(tasks)])
        targets = np.clip(targets, rows(tasks, "min_joint_pos"), rows(tasks, "max_joint_pos"))
        for j, task in enumerate(tasks):
            arm.command_arm(task.connection, targets[j], task.info)
            task.joint_targets, task.prev_action = targets[j], actions[j]

    @classmethod
    def raw_rows(cls, tasks: Sequence[SlideTask], states: RobotStates) -> np.ndarray:
        """N raw observations (21 + arm joints each, see the module docstring); velocity tracking moves on."""
        arm, connection = tasks[0].arm, tasks[0].connection
        ee = arm.ee_positions_of(connection, states)
        obj, obj_q = cls.object_poses_of(tasks, states)
        vel = cls.velocities(tasks, connection.observation_time(states), ee, obj, obj_q)
        return np.concatenate([ee, obj, obj - ee, quat_to_euler(obj_q), vel[:, 3:6], vel[:, 6:9], vel[:, 0:3],
                               arm.positions_of(states)], axis=1)

    def observation_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        base, reach = self.base_position, float(self.cfg["max_object_distance"]) + 0.1
        pos_lo, pos_hi = base + np.array([-reach, -reach, -0.5]), base + np.array([reach, reach, 0.7])
        rel = np.array([2 * reach, 2 * reach, 1.2])
        lin, ang = float(self.cfg["max_linear_velocity"]), float(self.cfg["max_angular_velocity"])
        one = np.ones(3)
        low = np.concatenate([pos_lo, pos_lo, -rel, -np.pi * one, -lin * one, -ang * one, -lin * one, self.chain.lower])
        high = np.concatenate([pos_hi, pos_hi, rel, np.pi * one, lin * one, ang * one, lin * one, self.chain.upper])
        return low, high

    def scripted_policy(self) -> ScriptedSlide:
        return ScriptedSlide(self.ee_delta_coeff, glide=PUCK["mass"] / PUCK["damping"])


class ScriptedSlide:
    """Pushes the puck along a line to the goal, faster while its glide falls short, and lets go once it will
    glide there.

    A puck let go at speed ``v`` glides ``v * glide * (1 - exp(-t / glide))`` in the ``t`` seconds left
    (``glide``: its drag's time constant), so each step says the speed it needs if let go now. The policy
    goes behind the puck, above it, down when nearly there, and creeps up to it at ``creep`` m/s (a fast
    touch knocks it on faster than the tool). Then it drives a point along the line from the puck's place
    at the touch to the goal at the puck's speed plus ``gain`` times what it lacks for a goal ``aim`` metres
    further (at most ``accel`` m/s more each step, at most ``max_speed``), and lets go, backing off and up
    out of the puck's way, at the first step where the puck's speed carries it to the goal.

    Why so: following a moving point makes every arm's tool keep to its speed, whatever its servos' lag or
    overrun; the puck rides on the tool, or is knocked ahead and caught up with again, and each step closes
    part of what it lacks, measured rather than modelled, in steps small enough (the gain and ``accel``)
    that the last one does not overshoot. The line is kept, not turned after a puck that drifts off it: the
    tool drags the puck sideways as it follows it, and the drift grows (the IRB120's pushes veered 5 cm).

    Reads only the observation (EE at 0:3, puck at 3:6, puck velocity at 12:15, the goal), a goal env's or a
    plain one's.
    """

    def __init__(self, ee_delta_coeff: float, glide: float, dt: float = 0.04, gain: float = 0.25,
                 accel: float = 0.05, max_speed: float = 0.6, creep: float = 0.1, aim: float = 0.015,
                 episode_steps: int = 50) -> None:
        self.coeff, self.glide, self.dt, self.gain, self.accel = ee_delta_coeff, glide, dt, gain, accel
        self.max_speed, self.creep, self.aim, self.episode_steps = max_speed, creep, aim, episode_steps
        self.reset()

    def reset(self) -> None:
        """Forget the episode (call at each episode start)."""
        self.released, self.phase, self.steps, self.rate, self.reference = False, "over", 0, 0.0, 0.0
        self.origin, self.direction, self.away = np.zeros(2), np.array([1.0, 0.0]), np.zeros(2)

    def __call__(self, obs: Any) -> np.ndarray:
        state = obs.get("observation") if isinstance(obs, dict) else obs
        if state is None or np.ndim(state) != 1:
            raise ValueError("the scripted slide reads the state observation: make the env with the state in it "
                             "(not rgb_obs_only)")
        o = np.asarray(state, dtype=np.float64)
        if isinstance(obs, dict) and "desired_goal" in obs:
            goal = np.asarray(obs["desired_goal"], dtype=np.float64)
        else:  # a plain env's: the goal, then goal minus puck, after the raw observation
            goal = o[-6:-3]
        ee, puck, vel = o[0:3], o[3:6], o[12:15]
        line = goal[:2] - puck[:2]
        dist = float(np.linalg.norm(line))
        u = line / max(dist, 1e-9)
        speed = float(vel[:2] @ u)
        # how far a puck let go now at 1 m/s glides in the seconds left
        reach = self.glide * (1.0 - math.exp(-max(self.episode_steps - self.steps, 1) * self.dt / self.glide))
        self.steps += 1
        if self.phase == "push" and speed * reach >= dist:
            self.released, self.phase, self.away = True, "away", ee[:2] - 0.05 * self.direction
        if self.released:  # it slides on: back off and up, out of its way
            return self._move(ee, np.array([*self.away, puck[2] + 0.06]))
        if self.phase == "over":  # to behind the puck, above it, down once nearly there
            behind = puck[:2] - u * (PUCK["radius"] + 0.035)  # clear of the tool's own width
            near = float(np.linalg.norm(ee[:2] - behind))
            if near >= 0.008 or ee[2] - puck[2] >= 0.012:
                return self._move(ee, np.array([*behind, puck[2] + (0.0 if near < 0.015 else 0.03)]))
            self.phase, self.rate, self.origin, self.direction = "touch", self.creep, puck[:2].copy(), u
            self.reference = float((ee[:2] - self.origin) @ u)
        if self.phase == "touch" and speed > 0.03:  # it moves: push it
            self.phase = "push"
        if self.phase == "push":
            need = (dist + self.aim) / reach
            wanted = min(speed + self.gain * (need - speed), self.max_speed)
            self.rate = max(min(wanted, self.rate + self.accel), self.creep)
        # the point on the line, never more than a step's reach ahead of the tool
        d = self.direction
        self.reference = min(self.reference + self.rate * self.dt, float((ee[:2] - self.origin) @ d) + self.coeff)
        return self._move(ee, np.array([*(self.origin + d * self.reference), puck[2]]))

    def _move(self, ee: np.ndarray, target: np.ndarray) -> np.ndarray:
        return np.clip((target - ee) / self.coeff, -1.0, 1.0).astype(np.float32)
