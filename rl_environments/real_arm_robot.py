"""The robot layer of a real arm: the same constants and helpers as the simulated
:class:`~rl_environments.arm_robot.ArmRobot`, over a robot's ROS 2 driver instead of the simulation node.

The end-effector position is forward kinematics of ``joint_states`` through the description
package's URDF (a real robot offers no end-effector service); arm targets go through the env's
:class:`~multiros.envs.real.safety.SafetyRules` to the JointTrajectoryController.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import numpy.typing as npt

from multiros.envs.real.safety import SafetyRules
from multiros.robot_state import RobotStates
from rl_environments.arm_robot import ArmRobot


def _velocity_limits(chain: Any) -> np.ndarray | None:
    """The chain's joint velocity limits (rad/s) when the description gives them all."""
    limits = np.asarray(chain.velocity_limits, dtype=np.float64)
    return limits if np.all(np.isfinite(limits)) and np.all(limits > 0) else None


class RealArmRobot(ArmRobot):
    """Robot-layer behaviour of a fixed-base arm driven through ros2_control.

    Class attributes a real robot sets (besides :class:`ArmRobot`'s):
        REAL_NAMESPACE: the driver's namespace.
        REAL_ARM_CONTROLLER: the JointTrajectoryController over ``ARM_JOINTS``.
        REAL_CONTROLLERS: other controllers that must be active.
        WORKSPACE_MIN, WORKSPACE_MAX: the box (world frame) the end effector must stay in.
        FLOOR_Z: lowest allowed end-effector height (world frame).
        MAX_JOINT_DELTA: largest joint change per command (rad).
    """

    REAL_NAMESPACE: ClassVar[str]
    REAL_ARM_CONTROLLER: ClassVar[str]
    REAL_CONTROLLERS: ClassVar[tuple[str, ...]] = ()
    WORKSPACE_MIN: ClassVar[tuple[float, float, float]]
    WORKSPACE_MAX: ClassVar[tuple[float, float, float]]
    FLOOR_Z: ClassVar[float] = 0.02
    MAX_JOINT_DELTA: ClassVar[float] = 0.15

    if TYPE_CHECKING:  # the real env core's, below this layer
        safety: SafetyRules | None

        def send_joint_targets(self, targets: Sequence[float] | np.ndarray) -> Any: ...

    @classmethod
    def real_robot_kwargs(cls, overrides: Mapping[str, Any]) -> dict[str, Any]:
        """:class:`~multiros.envs.RealBaseEnv` arguments for this robot; ``overrides`` (user kwargs) win.

        Robot-layer options (popped here): ``base_position`` (world position of the base, default the
        origin), ``workspace_min``/``workspace_max``/``floor_z`` (``None`` disables that check),
        ``max_joint_delta``, ``workspace_mode`` (``"project"`` or ``"refuse"``).
        """
        opts = dict(overrides)
        base = np.asarray(opts.pop("base_position", (0.0, 0.0, 0.0)), dtype=np.float64).reshape(3)
        ws_min = opts.pop("workspace_min", cls.WORKSPACE_MIN)
        ws_max = opts.pop("workspace_max", cls.WORKSPACE_MAX)
        floor = opts.pop("floor_z", cls.FLOOR_Z)
        chain = cls.kinematic_chain()
        if tuple(chain.joint_names) != tuple(cls.ARM_JOINTS):
            raise ValueError(f"{cls.__name__}: chain joints {chain.joint_names} differ from ARM_JOINTS "
                             f"{cls.ARM_JOINTS}")
        safety = SafetyRules(
            cls.ARM_JOINTS, lower=chain.lower, upper=chain.upper,
            max_joint_delta=opts.pop("max_joint_delta", cls.MAX_JOINT_DELTA), max_velocity=_velocity_limits(chain),
            chain=chain, base_position=base,
            workspace_min=ws_min, workspace_max=ws_max, floor_z=floor,
            workspace_mode=opts.pop("workspace_mode", "project"),
        )
        kwargs: dict[str, Any] = {
            "namespace": cls.REAL_NAMESPACE,
            "robot_name": cls.ROBOT_NAME,
            "arm_joints": cls.ARM_JOINTS,
            "arm_controller": cls.REAL_ARM_CONTROLLER,
            "controllers_list": list(cls.REAL_CONTROLLERS),
            "safety": safety,
        }
        kwargs.update(opts)
        kwargs["_base_position"] = base
        return kwargs

    def _take_base(self, kwargs: dict[str, Any]) -> dict[str, Any]:
        self._base_position = kwargs.pop("_base_position")
        self._ee_cache: tuple[Any, np.ndarray] | None = None
        return kwargs

    def apply_task_joint_limits(self, lower: npt.ArrayLike, upper: npt.ArrayLike) -> None:
        """Tighten the safety rules' joint limits to the task config's (the tighter bound wins)."""
        rules = self.safety
        assert rules is not None, "a real arm's env has safety rules"
        self.safety = SafetyRules(
            rules.joint_names, lower=lower, upper=upper, description_lower=rules.lower, description_upper=rules.upper,
            max_joint_delta=rules.max_joint_delta, max_velocity=rules.max_velocity, chain=rules.chain,
            base_position=rules.base_position,
            workspace_min=rules.workspace_min, workspace_max=rules.workspace_max, floor_z=rules.floor_z,
            workspace_mode=rules.workspace_mode, path_samples=rules.path_samples,
        )

    # -- the robot layer, batch-first (see rl_environments.arm_interface) -----------------------------
    @classmethod
    def ee_positions_of(cls, envs: Sequence[Any], states: RobotStates) -> np.ndarray:
        """End-effector world positions: forward kinematics of the observed arm joint positions (a real
        robot offers no end-effector pose; the sim's frame is the same link of the same description)."""
        chain = cls.kinematic_chain()
        base = np.array([env.base_position for env in envs])
        return chain.fk_position(cls.arm_positions_of(states)) + base

    @classmethod
    def set_arm_targets_of(cls, envs: Sequence[Any], targets: np.ndarray) -> None:
        """Command each env's arm through its safety rules (``info["safety"]`` says what they did)."""
        for env, row in zip(envs, targets):
            env.send_joint_targets(row)

    # -- the same for one env ------------------------------------------------------------------------
    @property
    def base_position(self) -> np.ndarray:
        """World position of the robot base (``base_position`` option; the origin by default)."""
        return self._base_position.copy()

    def ee_position(self) -> np.ndarray:
        """End-effector world position: forward kinematics of the observed arm joint positions."""
        state = self.robot_state
        cached = self._ee_cache
        if cached is not None and cached[0] is state:
            return cached[1].copy()
        ee = self.kinematic_chain().fk_position(self.arm_positions()) + self._base_position
        self._ee_cache = (state, ee)
        return ee.copy()
