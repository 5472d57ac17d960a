"""MujocoBaseEnv / MujocoGoalEnv: every hook path, seeding, reset and step modes, faults, check_env.

The envs here drive the small 3-joint test arm of ``tests/sim/data`` through a composed
simulation node (in-process transport).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env

from multiros.envs import EnvError, MujocoBaseEnv, MujocoGoalEnv, ResetError
from multiros.envs.GazeboBaseEnv import GazeboBaseEnv
from multiros.envs.GazeboGoalEnv import GazeboGoalEnv

DATA = Path(__file__).resolve().parent.parent / "sim" / "data"
JOINTS = ("joint1", "joint2", "joint3")
HOME = np.array([0.0, 0.3, 0.0])
TOL = 0.05


@pytest.fixture(autouse=True)
def _test_packages(monkeypatch):
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(DATA))


def _robot_kwargs(**overrides):
    kwargs = dict(
        robot_name="arm",
        robot_model_xml="package://test_arm_description/urdf/arm.urdf.xacro",
        controllers_list=["joint_state_broadcaster", "arm_position_controller"],
        frames=["ee_link"],
        num_sim_steps=10,
    )
    kwargs.update(overrides)
    return kwargs


def _goal_spaces():
    box = spaces.Box(-2.0, 2.0, shape=(3,), dtype=np.float32)
    observation = spaces.Box(-10.0, 10.0, shape=(6,), dtype=np.float32)
    return spaces.Dict({"observation": observation, "achieved_goal": box, "desired_goal": box})


class CanonicalGoalEnv(MujocoGoalEnv):
    """The canonical hook set (docs/envs.md)."""

    def __init__(self, **kwargs):
        super().__init__(**_robot_kwargs(**kwargs))
        self.action_space = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        self.observation_space = _goal_spaces()
        self.goal = np.zeros(3)
        self.calls: list[str] = []

    def _check_connection_and_readiness(self):
        self.calls.append("ready")
        return True

    def _set_init_pose(self):
        self.calls.append("init_pose")
        self.move_to_initial_pose(JOINTS, HOME)

    def _set_episode_init_params(self):
        self.calls.append("episode_params")
        self.goal = self.np_random.uniform([0.05, -0.1, 0.3], [0.15, 0.1, 0.45])

    def _set_action(self, action):
        self.send_command("arm_position_controller", self.joint_positions(JOINTS) + 0.1 * action)

    def _get_obs(self):
        q = self.joint_positions(JOINTS)
        qd = np.clip(self.joint_velocities(JOINTS), -7, 7)
        ee = self.frame_position("ee_link")
        return {
            "observation": np.concatenate([q, qd]).astype(np.float32),
            "achieved_goal": ee.astype(np.float32),
            "desired_goal": self.goal.astype(np.float32),
        }

    def _compute_reward(self, achieved_goal, desired_goal, info):
        d = np.linalg.norm(np.asarray(achieved_goal) - np.asarray(desired_goal), axis=-1)
        return -(d > TOL).astype(np.float32)

    def _is_success(self, achieved_goal, desired_goal):
        return np.linalg.norm(np.asarray(achieved_goal) - np.asarray(desired_goal), axis=-1) <= TOL


class MultirosPlainEnv(GazeboBaseEnv):
    """Hooks with MultiROS' names, through the GazeboBaseEnv alias."""

    def __init__(self, **kwargs):
        super().__init__(**_robot_kwargs(**kwargs))
        self.action_space = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        self.observation_space = spaces.Box(-10.0, 10.0, shape=(6,), dtype=np.float32)
        self.calls: list[str] = []

    def _check_connection_and_readiness(self):
        self.calls.append("ready")
        return True

    def _set_init_params(self, options=None):
        self.calls.append(f"init_params:{options}")
        self.set_joint_positions(JOINTS, HOME)

    def _set_action(self, action):
        self.send_command("arm_position_controller", self.joint_positions(JOINTS) + 0.1 * action)

    def _get_observation(self):
        return np.concatenate([self.joint_positions(JOINTS), np.clip(self.joint_velocities(JOINTS), -7, 7)]).astype(
            np.float32
        )

    def _get_reward(self, info=None):
        info["reward_seen"] = True
        return -float(np.linalg.norm(self.joint_positions(JOINTS) - [0.5, 0.5, 0.5]))

    def _compute_terminated(self, info=None):
        return False

    def _compute_truncated(self, info=None):
        return self.sim_time > 1.0


class FrobsEnv(MujocoBaseEnv):
    """Hooks with FRobs_RL's names."""

    def __init__(self, **kwargs):
        super().__init__(**_robot_kwargs(**kwargs))
        self.action_space = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        self.observation_space = spaces.Box(-10.0, 10.0, shape=(3,), dtype=np.float32)
        self.checked = 0

    def _check_subs_and_pubs_connection(self):
        self.checked += 1
        return True

    def _set_episode_init_params(self):
        self.set_joint_positions(JOINTS, HOME)

    def _send_action(self, action):
        self.send_command("arm_position_controller", self.joint_positions(JOINTS) + 0.1 * action)

    def _get_observation(self):
        return self.joint_positions(JOINTS).astype(np.float32)

    def _get_reward(self):
        return 1.0

    def _check_if_done(self):
        self.info["is_success"] = 1.0
        return True


class MultirosGoalEnv(GazeboGoalEnv):
    """A MultiROS goal env: public compute_* and the three observation getters."""

    def __init__(self, **kwargs):
        super().__init__(**_robot_kwargs(**kwargs))
        self.action_space = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        self.observation_space = _goal_spaces()
        self.goal = np.array([0.1, 0.0, 0.4])

    def _set_init_params(self, options=None):
        self.set_joint_positions(JOINTS, HOME)

    def _set_action(self, action):
        self.send_command("arm_position_controller", self.joint_positions(JOINTS) + 0.1 * action)

    def _get_observation(self):
        return np.concatenate([self.joint_positions(JOINTS), np.clip(self.joint_velocities(JOINTS), -7, 7)]).astype(
            np.float32
        )

    def _get_achieved_goal(self):
        return self.frame_position("ee_link").astype(np.float32)

    def _get_desired_goal(self):
        return self.goal.astype(np.float32)

    def compute_reward(self, achieved_goal, desired_goal, info):
        return -np.linalg.norm(np.asarray(achieved_goal) - np.asarray(desired_goal), axis=-1)

    def compute_terminated(self, achieved_goal, desired_goal, info):
        return np.linalg.norm(np.asarray(achieved_goal) - np.asarray(desired_goal), axis=-1) < 0.01


@pytest.fixture
def make():
    envs = []

    def _make(cls, **kwargs):
        env = cls(**kwargs)
        envs.append(env)
        return env

    yield _make
    for env in envs:
        env.close()


def _rollout(env, seed, n=15):
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(0)
    frames = [obs]
    for _ in range(n):
        obs, *_ = env.step(rng.uniform(-1, 1, 3).astype(np.float32))
        frames.append(obs)
    return frames


def _flat(frames):
    return np.concatenate(
        [np.concatenate([f[k] for k in sorted(f)]) if isinstance(f, dict) else f for f in frames]
    )


def test_canonical_hooks_run_in_order_and_goal_obs(make):
    env = make(CanonicalGoalEnv)
    obs, info = env.reset(seed=1)
    assert env.calls == ["ready", "init_pose", "episode_params"]
    assert env.observation_space.contains(obs)
    assert "is_success" in info
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    assert reward == env.compute_reward(obs["achieved_goal"], obs["desired_goal"], info)
    assert isinstance(info["is_success"], bool)
    assert terminated == bool(info["is_success"])


def test_multiros_hook_names(make):
    env = make(MultirosPlainEnv)
    obs, _ = env.reset(options={"x": 1})
    assert env.calls == ["ready", "init_params:{'x': 1}"]
    np.testing.assert_allclose(obs[:3], HOME, atol=1e-9)
    obs, reward, terminated, truncated, info = env.step(np.zeros(3, np.float32))
    assert info["reward_seen"] and reward < 0 and not terminated and info["is_success"] is False


def test_multiros_truncation_hook(make):
    env = make(MultirosPlainEnv, num_sim_steps=200)  # 0.4 s per step
    env.reset()
    truncs = [env.step(np.zeros(3, np.float32))[3] for _ in range(4)]
    assert truncs == [False, False, True, True]


def test_frobs_hook_names(make):
    env = make(FrobsEnv)
    env.reset()
    assert env.checked == 1
    obs, reward, terminated, truncated, info = env.step(np.zeros(3, np.float32))
    assert reward == 1.0 and terminated and info["is_success"] == 1.0


def test_multiros_goal_env(make):
    env = make(MultirosGoalEnv)
    obs, _ = env.reset()
    assert set(obs) == {"observation", "achieved_goal", "desired_goal"}
    obs, reward, *_ = env.step(np.zeros(3, np.float32))
    assert reward == pytest.approx(-np.linalg.norm(obs["achieved_goal"] - obs["desired_goal"]), rel=1e-5)


def test_vectorised_compute_reward_matches_scalar(make):
    env = make(CanonicalGoalEnv)
    rng = np.random.default_rng(0)
    ag = rng.uniform(-0.1, 0.1, (64, 3))
    dg = ag + rng.normal(0, 0.05, (64, 3))
    batch = env.compute_reward(ag, dg, [{}] * 64)
    single = np.array([env.compute_reward(a, d, {}) for a, d in zip(ag, dg)])
    np.testing.assert_array_equal(batch, single)
    assert batch.shape == (64,)
    term = env.compute_terminated(ag, dg, [{}] * 64)
    assert term.shape == (64,) and term.dtype == bool
    assert env.compute_truncated(ag, dg, [{}] * 64).shape == (64,)


@pytest.mark.parametrize("cls", [CanonicalGoalEnv, MultirosPlainEnv])
def test_gymnasium_check_env(make, cls):
    check_env(make(cls), skip_render_check=True)


def test_sb3_check_env(make):
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    sb3_check_env(make(CanonicalGoalEnv), warn=True)


def test_same_seed_same_episode_and_seed_consumed_once(make):
    a, b = make(CanonicalGoalEnv), make(CanonicalGoalEnv)
    assert _flat(_rollout(a, 7)).tobytes() == _flat(_rollout(b, 7)).tobytes()
    # reset() without a seed continues the stream: a new goal, not the seeded one again.
    goal_first = a.goal.copy()
    a.reset()
    assert not np.allclose(a.goal, goal_first)
    # A constructor seed is used by the first reset only.
    c, d = make(CanonicalGoalEnv, seed=7), make(CanonicalGoalEnv, seed=7)
    c.reset()
    d.reset()
    np.testing.assert_array_equal(c.goal, d.goal)
    g1 = c.goal.copy()
    c.reset()
    assert not np.array_equal(c.goal, g1)


def test_global_numpy_rng_is_not_used(make):
    env = make(CanonicalGoalEnv)
    np.random.seed(123)
    expected = np.random.random()
    np.random.seed(123)
    _rollout(env, 3, n=5)
    assert np.random.random() == expected


def test_reset_modes(make):
    world = make(CanonicalGoalEnv, reset_mode="world")
    world.reset()
    world.step(np.zeros(3, np.float32))
    world.reset()
    assert world.sim_time > 0  # "world" keeps simulation time
    sim = make(CanonicalGoalEnv, reset_mode=2)  # FRobs' 2 = reset_simulation
    sim.reset()
    sim.step(np.zeros(3, np.float32))
    sim.reset()
    assert sim.sim_time == 0.0
    with pytest.raises(ValueError, match="reset_mode"):
        make(CanonicalGoalEnv, reset_mode="bogus")


def test_lockstep_advances_num_sim_steps(make):
    env = make(CanonicalGoalEnv, num_sim_steps=25)
    env.reset()
    t0 = env.sim_time
    env.step(np.zeros(3, np.float32))
    assert env.sim_time - t0 == pytest.approx(25 * 0.002)


@pytest.mark.parametrize("mode", ["pause_unpause", "realtime", 1])
def test_wall_clock_step_modes_advance_time(make, mode):
    env = make(CanonicalGoalEnv, step_mode=mode, action_cycle_time=0.05, real_time_factor=1.0)
    env.reset()
    t0 = env.sim_time
    env.step(np.zeros(3, np.float32))
    assert env.sim_time > t0
    with pytest.raises(ValueError, match="action_cycle_time"):
        make(CanonicalGoalEnv, step_mode=mode)


def test_bad_actions_are_refused(make):
    env = make(CanonicalGoalEnv)
    env.reset()
    with pytest.raises(ValueError, match="NaN"):
        env.step(np.array([np.nan, 0, 0], np.float32))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(4, np.float32))
    obs, *_ = env.step(np.full(3, 50.0, np.float32))  # clipped into the space
    assert env.observation_space.contains(obs)


def test_zero_quaternion_and_unknown_kwargs_are_refused():
    with pytest.raises(ValueError, match="quaternion"):
        CanonicalGoalEnv(robot_ori_w=0.0)
    with pytest.raises(TypeError, match="bogus_knob"):
        CanonicalGoalEnv(bogus_knob=1)


def test_unreachable_initial_pose_raises_reset_error(make):
    class BadPose(CanonicalGoalEnv):
        def _set_init_pose(self):
            self.move_to_initial_pose(JOINTS, [0.0, 0.3, 0.0], tolerance=-1.0)

    env = make(BadPose, max_reset_attempts=2)
    with pytest.raises(ResetError, match="2 attempts"):
        env.reset()


def test_a_step_after_a_failed_reset_raises_the_env_s_error(make):
    """Through gym.make's wrappers (the env checker, order enforcing, time limit): the step after a
    reset that raised names that reset's error (it used to be the env checker's TypeError), and
    nothing is stepped (tests/tasks/test_tasks.py: the retry through uniros.make)."""
    from gymnasium.wrappers import OrderEnforcing, PassiveEnvChecker, TimeLimit

    from multiros.envs.errors import StepAfterFailedReset

    class BadPose(CanonicalGoalEnv):
        def _set_init_pose(self):
            self.move_to_initial_pose(JOINTS, [0.0, 0.3, 0.0], tolerance=-1.0)

    raw = make(BadPose, max_reset_attempts=1)
    env = TimeLimit(OrderEnforcing(PassiveEnvChecker(raw)), max_episode_steps=5)
    with pytest.raises(ResetError):
        env.reset(seed=0)
    before = raw.sim_time
    with pytest.raises(StepAfterFailedReset, match=r"BadPose.step\(\) after a reset that failed \(ResetError: "):
        env.step(raw.action_space.sample())
    assert raw.sim_time == before  # refused before the simulation stepped


def test_unknown_frame_and_joint_errors(make):
    env = make(CanonicalGoalEnv)
    env.reset()
    with pytest.raises(EnvError, match="frames"):
        env.frame_position("nope")
    with pytest.raises(EnvError, match="no joint"):
        env.joint_positions(["nope"])


def test_close_releases_the_composed_node(make):
    env = CanonicalGoalEnv()
    env.reset()
    ctx = env.sim_connection.context
    env.close()
    env.close()  # idempotent
    assert not ctx.ok()


def test_two_envs_do_not_interfere(make):
    a, b = make(CanonicalGoalEnv), make(CanonicalGoalEnv)
    a.reset(seed=0)
    b.reset(seed=0)
    for _ in range(5):
        a.step(np.ones(3, np.float32))
    assert b.sim_time == 0.0 or b.sim_time < a.sim_time
    np.testing.assert_allclose(b.joint_positions(JOINTS), HOME, atol=1e-6)


def test_task_layer_multiros_hook_is_not_hidden_by_robot_layer_canonical_hook(make):
    class RobotLayer(MultirosPlainEnv):
        def _check_if_done(self):  # canonical robot-layer name
            return False

    class TaskLayer(RobotLayer):
        def _compute_terminated(self, info=None):  # MultiROS task-layer name, more derived
            return True

    env = make(TaskLayer)
    env.reset()
    assert env.step(np.zeros(3, np.float32))[2] is True


def test_reset_controllers_restarts_them_on_reset(make):
    env = make(CanonicalGoalEnv, reset_controllers=True)
    env.reset(seed=0)
    env.step(np.ones(3, np.float32))
    env.reset()
    states = {c.name: c.state for c in env.sim.list_controllers(env.namespace)}
    assert states == {"joint_state_broadcaster": "active", "arm_position_controller": "active"}
    np.testing.assert_allclose(env.joint_positions(JOINTS), HOME, atol=1e-6)
    from multiros.sim.client import SimulationServiceError

    with pytest.raises(SimulationServiceError, match="refused"):
        env.sim.switch_controllers(env.namespace, activate=["no_such_controller"])
