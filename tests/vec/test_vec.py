"""Batched vector envs (one simulation node, one StepRobots per step): equality with N separate
envs, autoreset, world slots, faults, limits, the SB3 adapter with HER, and the node's StepRobots /
GetNodeLoad services."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode, SyncVectorEnv

import uniros
from multiros.envs.vector import autoreset_mode_of
from multiros.ros import Context, Node
from multiros.ros.interfaces import type_hash
from multiros.sim.client import RobotStepSpec, SimulationClient, SimulationServiceError
from multiros.sim.launch import compose

ENV = "RX200ReacherGoalSim-v0"
RX200 = ("package://rx200_description/urdf/rx200.urdf.xacro?robot_name=rx200"
         "&__controllers=joint_state_broadcaster,arm_position_controller,gripper_controller")


def _assert_same(a, b) -> None:
    if isinstance(a, dict):
        assert a.keys() == b.keys()
        for k in a:
            np.testing.assert_array_equal(a[k], b[k], err_msg=k)
    else:
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize(("mode", "num_nodes"), [(AutoresetMode.NEXT_STEP, 1), (AutoresetMode.SAME_STEP, 1),
                                               (AutoresetMode.NEXT_STEP, 2)])
def test_batched_equals_separate_envs_step_for_step(mode: AutoresetMode, num_nodes: int) -> None:
    """Same seeds and actions: identical observations, rewards, terminations, truncations and
    autoresets as Gymnasium's SyncVectorEnv over N separate envs (each with its own node); also
    with the robots on two composed nodes stepped at once on threads."""
    n, horizon = 3, 12
    batched = uniros.make_vec(ENV, n, vectorization_mode="batched", max_episode_steps=horizon,
                              vector_kwargs={"autoreset_mode": mode, "num_nodes": num_nodes})
    separate = SyncVectorEnv([lambda: uniros.make(ENV, max_episode_steps=horizon) for _ in range(n)],
                             autoreset_mode=mode)
    try:
        assert batched.batch.task is not None  # the goal reach task steps batch-first
        assert batched.metadata["autoreset_mode"] == mode
        assert batched.single_observation_space == separate.single_observation_space
        assert batched.action_space == separate.action_space
        obs_b, _ = batched.reset(seed=7)
        obs_s, _ = separate.reset(seed=7)
        _assert_same(obs_b, obs_s)
        rng = np.random.default_rng(0)
        ended = 0
        for _ in range(2 * horizon + 3):  # crosses two autoresets of every env
            actions = rng.uniform(-1, 1, (n, 5)).astype(np.float32)
            ob, rb, tb, trb, ib = batched.step(actions)
            os_, rs, ts, trs, is_ = separate.step(actions)
            _assert_same(ob, os_)
            np.testing.assert_array_equal(rb, rs)
            np.testing.assert_array_equal(tb, ts)
            np.testing.assert_array_equal(trb, trs)
            np.testing.assert_array_equal(ib["is_success"], is_["is_success"])
            if mode == AutoresetMode.SAME_STEP and "final_obs" in is_:
                np.testing.assert_array_equal(ib["_final_obs"], is_["_final_obs"])
                for i in np.flatnonzero(is_["_final_obs"]):
                    _assert_same(ib["final_obs"][i], is_["final_obs"][i])
            ended += int(np.sum(tb | trb))
        assert ended >= 2 * n
    finally:
        batched.close()
        separate.close()


def test_a_batch_step_runs_each_connections_checks_before_acting_as_one_env_does() -> None:
    """One act half for one env and a batch (multiros.envs.batch_task.act_rows): every env's
    connection's ``before_act`` (a robot's watchdog) runs once per step, before its commands."""
    batched = uniros.make_vec(ENV, 2, vectorization_mode="batched", max_episode_steps=20)
    single = uniros.make(ENV)
    try:
        assert batched.batch.task is not None
        calls: list[str] = []
        envs = [*batched.batch.envs, single.unwrapped]
        for k, env in enumerate(envs):
            env.connection.before_act = (lambda k=k: calls.append(f"env{k}"))  # type: ignore[method-assign]
        batched.reset(seed=0)
        single.reset(seed=0)
        batched.step(np.zeros((2, 5), np.float32))
        single.step(np.zeros(5, np.float32))
        assert calls == ["env0", "env1", "env2"]
    finally:
        batched.close()
        single.close()


def test_next_step_autoreset_semantics_and_slots() -> None:
    """NEXT_STEP: the step after an episode ends ignores that env's action and returns its first
    observation with reward 0; robots sit in their own slots, namespaces, and never touch."""
    vec = uniros.make_vec(ENV, 4, vectorization_mode="batched", max_episode_steps=3, vector_kwargs={"num_nodes": 1})
    try:
        obs, _ = vec.reset(seed=1)
        first = {k: v.copy() for k, v in obs.items()}
        zero = np.zeros((4, 5), np.float32)
        for _ in range(2):
            _, _, _, trunc, _ = vec.step(zero + 1.0)
            assert not trunc.any()
        _, _, _, trunc, _ = vec.step(zero + 1.0)
        assert trunc.all()
        obs, reward, term, trunc, _ = vec.step(zero - 1.0)  # ignored: this step resets
        assert not term.any() and not trunc.any() and np.all(reward == 0.0)
        np.testing.assert_array_equal(obs["observation"][:, :3], first["observation"][:, :3])  # EE at start pose
        names = vec.get_attr("robot_name")
        assert len(set(names)) == 4 and all(n.startswith("rx200_") for n in names)
        assert [e.namespace for e in vec.envs] == ["/" + n for n in names]
        world = vec.batch.connections[0].sim_node.world
        bases = [world.get_entity_state(n).position for n in names]
        gaps = [np.linalg.norm(a - b) for i, a in enumerate(bases) for b in bases[i + 1:]]
        assert min(gaps) >= 2.0 - 1e-9
        # relative to its slot every robot reports the same end-effector position as alone
        np.testing.assert_allclose(obs["achieved_goal"], np.repeat(obs["achieved_goal"][:1], 4, axis=0), atol=1e-6)
        m, d = world.model, world.data
        for c in d.contact[: d.ncon]:
            owners = {_entity_of(m, world, int(g)) for g in (c.geom1, c.geom2)} - {None}
            assert len(owners) <= 1, owners
        assert vec.call("compute_reward", obs["achieved_goal"], obs["desired_goal"], [{}] * 4)[0].shape == (4,)
    finally:
        vec.close()


def _entity_of(m, world, geom: int) -> str | None:
    import mujoco

    body = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.geom_bodyid[geom])) or ""
    return next((n for n in world.entity_names() if body.startswith(n + "/")), None)


@pytest.mark.parametrize(("num_nodes", "bad"), [(1, 1), (2, 1), (2, 2)])
def test_diverging_or_refused_robot_ends_its_episode_alone(num_nodes: int, bad: int) -> None:
    """Also on two composed nodes: robot 1 is on node 0 (stepped on the calling thread), robot 2 on
    node 1 (stepped on a worker thread)."""
    vec = uniros.make_vec(ENV, 3, vectorization_mode="batched", vector_kwargs={"num_nodes": num_nodes})
    try:
        vec.reset(seed=0)
        actions = np.zeros((3, 5), np.float32)
        vec.step(actions)
        world = vec.batch.connections[vec.batch.node_of[bad]].sim_node.world
        ent = world._entities[vec.envs[bad].robot_name]
        world.data.qvel[ent.dof_idx] = np.nan  # robot `bad`'s physics blows up in the next step
        expected = [i == bad for i in range(3)]
        obs, _, _, trunc, info = vec.step(actions)
        assert trunc.tolist() == expected
        assert info["sim_diverged"][bad] and info["_sim_diverged"].tolist() == expected
        assert "diverged" in info["sim_error"][bad]
        assert np.all(np.isfinite(obs["observation"]))
        # a command the node refuses (wrong length) ends env 0's episode, not the others'
        link = vec.envs[0].connection
        queue = link.command
        link.command = lambda controller, values: queue(controller, np.ones(2))  # a length the node refuses
        _, reward, _, trunc, info = vec.step(actions)  # env `bad` autoresets here
        assert trunc.tolist() == [True, False, False] and reward[bad] == 0.0
        assert "arm_position_controller" in info["sim_error"][0] or "command" in info["sim_error"][0]
        del link.command
        _, _, _, trunc, _ = vec.step(actions)  # env 0 autoresets, all step on
        assert not trunc.any()
        with pytest.raises(ValueError, match="NaN"):
            vec.step(np.full((3, 5), np.nan, np.float32))
        for wrong in (np.zeros((2, 5), np.float32), np.zeros((3, 4), np.float32), np.zeros(5, np.float32)):
            with pytest.raises(ValueError, match=r"give an array of shape \(3, 5\)"):
                vec.step(wrong)  # one clear error, nothing stepped (was an IndexError)
    finally:
        vec.close()


def test_num_envs_beyond_node_limit_is_refused() -> None:
    with pytest.raises(ValueError, match="max_robots=256"):
        uniros.make_vec(ENV, 300, vectorization_mode="batched", vector_kwargs={"num_nodes": 1})
    with pytest.raises(ValueError, match="num_nodes must be an integer from 1 to num_envs"):
        uniros.make_vec(ENV, 2, vectorization_mode="batched", vector_kwargs={"num_nodes": 3})
    with pytest.raises(TypeError, match="unknown batched vector env option"):
        uniros.make_vec(ENV, 2, vectorization_mode="batched", vector_kwargs={"nodes": 2})


@pytest.mark.parametrize("given", ["SAME_STEP", "SameStep", "same_step", AutoresetMode.SAME_STEP])
def test_autoreset_mode_by_name_or_value(given: AutoresetMode | str) -> None:
    # The docs name the modes as the enum's members (SAME_STEP); Gymnasium's strings are the values.
    assert autoreset_mode_of(given) is AutoresetMode.SAME_STEP
    assert autoreset_mode_of("next_step") is AutoresetMode.NEXT_STEP
    assert autoreset_mode_of("Disabled") is AutoresetMode.DISABLED


@pytest.mark.parametrize("layout", [{"workers": 0}, {"workers": 1}])
def test_unknown_autoreset_mode_is_refused_naming_the_modes(layout: dict) -> None:
    with pytest.raises(ValueError, match="'NEXT_STEP', 'SAME_STEP', 'DISABLED'"):
        uniros.make_vec(ENV, 2, vector_kwargs={"autoreset_mode": "SAMESTEPS", **layout})
    vec = uniros.make_vec(ENV, 2, vector_kwargs={"autoreset_mode": "SAME_STEP", **layout})
    try:
        assert vec.metadata["autoreset_mode"] is AutoresetMode.SAME_STEP
    finally:
        vec.close()


def test_gymnasium_sync_mode_still_works() -> None:
    vec = uniros.make_vec(ENV, 2, vectorization_mode="sync")
    try:
        obs, _ = vec.reset(seed=0)
        assert obs["observation"].shape[0] == 2
    finally:
        vec.close()


def test_node_step_robots_and_load() -> None:
    """StepRobots per-robot results, refusals, and GetNodeLoad; SpawnEntity beyond max_robots."""
    ctx = Context(transport="inproc").init()
    try:
        node = compose("mujoco_sim", context=ctx, max_robots=2)
        client = SimulationClient(Node("t", context=ctx), "/mujoco_sim")
        client.spawn_entity("a", uri=RX200, namespace="/a")
        client.spawn_entity("b", uri=RX200, namespace="/b", position=(2.0, 0.0, 0.0))
        with pytest.raises(SimulationServiceError, match="max_robots=2"):
            client.spawn_entity("c", uri=RX200, namespace="/c", position=(4.0, 0.0, 0.0))
        assert client.get_entities() == ["a", "b"]
        ee = "rx200/ee_gripper_link"
        out = client.step_robots([
            RobotStepSpec("a", {"arm_position_controller": [0.3, 0, 0, 0, 0]}, [ee]),
            RobotStepSpec("b", {"arm_position_controller": [0.3]}, [ee]),
        ], steps=20)
        assert [o.status for o in out] == [0, 102]
        missing = client.step_robots([RobotStepSpec("nobody"), RobotStepSpec("a", frames=["no_such_link"])], steps=0)
        assert [o.status for o in missing] == [105, 103]
        assert missing[0].state is None and "nobody" in missing[0].message
        assert out[0].state.position[0] > 0.05 and abs(out[1].state.position[0]) < 1e-3
        np.testing.assert_allclose(out[1].state.frame_positions[0] - out[0].state.frame_positions[0],
                                   [2.0, 0, 0], atol=0.15)  # a turned its waist a little
        client.reset_robot("a")
        out = client.step_robots([RobotStepSpec("a", frames=[ee]), RobotStepSpec("b", frames=[ee])], steps=0)
        assert abs(out[0].state.position[0]) < 1e-9
        with pytest.raises(SimulationServiceError, match="more than once"):
            client.step_robots([RobotStepSpec("a"), RobotStepSpec("a")], steps=1)
        with pytest.raises(SimulationServiceError, match="max_robots=2"):
            client.step_robots([RobotStepSpec("a"), RobotStepSpec("b"), RobotStepSpec("c")], steps=1)
        load = client.get_node_load()
        assert load["robots"] == 2 and load["max_robots"] == 2 and load["entities"] == 2
        assert load["physics_steps"] == 20 and load["physics_steps_per_sec"] > 0
        assert 0 < load["busy_fraction"] <= 1 and load["model_bytes"] > 100_000 and load["process_rss_bytes"] > 0
        assert node.get_parameter("max_robots").value == 2
    finally:
        ctx.try_shutdown()


def _reply_equals_outcomes(outcomes, reply) -> None:
    assert [(o.status, o.message) for o in outcomes] == list(zip(reply.status, reply.message))
    for outcome, state in zip(outcomes, reply.states):
        assert (outcome.state is None) == (state is None)
        if state is not None:
            assert outcome.state.sim_time == state.sim_time == reply.sim_time and outcome.state.names == state.names
            for field in ("position", "velocity", "effort", "frame_positions", "frame_orientations"):
                np.testing.assert_array_equal(getattr(outcome.state, field), getattr(state, field), err_msg=field)


def test_composed_stepper_answers_as_the_service() -> None:
    """A ComposedStepper (what envs on a composed node call: no messages) returns what the
    StepRobots service returns, bit for bit: two identical nodes, one called each way; also the
    per-robot failures and the refusals of a whole call. ServiceStepper answers the same."""
    from multiros.sim.stepper import ComposedStepper, ServiceStepper

    ctx = Context(transport="inproc").init()
    try:
        nodes, clients = [], []
        for name in ("sim_service", "sim_local"):
            nodes.append(compose(name, context=ctx, max_robots=3))
            clients.append(SimulationClient(Node(f"t_{name}", context=ctx), f"/{name}"))
            clients[-1].spawn_entity("a", uri=RX200, namespace=f"/{name}/a")
            clients[-1].spawn_entity("b", uri=RX200, namespace=f"/{name}/b", position=(2.0, 0.0, 0.0))
        local = ComposedStepper(nodes[1])
        ee = "rx200/ee_gripper_link"
        calls = [
            ([RobotStepSpec("a", {"arm_position_controller": [0.3, -0.2, 0.1, 0, 0.4]}, [ee]),
              RobotStepSpec("b", {"arm_position_controller": [0.3]}, [ee])], 20),  # b: wrong length
            ([RobotStepSpec("a", {"arm_position_controller": np.array([0.1, 0, 0, 0.2, 0])}, [ee, "rx200/base_link"]),
              RobotStepSpec("b", {"no_such_controller": [0.0]})], 7),
            ([RobotStepSpec("nobody"), RobotStepSpec("a", frames=["no_such_link"])], 0),
            ([RobotStepSpec("a", reset=True, frames=[ee]), RobotStepSpec("b", frames=[ee])], 3),
        ]
        two_frames = [ee, "rx200/base_link"]
        alike = [
            ([RobotStepSpec("a", {"arm_position_controller": [0.2, 0.1, 0, 0, 0.3]}, two_frames),
              RobotStepSpec("b", {"arm_position_controller": [-0.2, 0.3, 0.1, 0, 0]}, two_frames)], 5),
            ([RobotStepSpec("a"), RobotStepSpec("b")], 2),  # no frames
        ]
        for specs, steps in calls:
            by_service = clients[0].step_robots(specs, steps=steps)
            reply = local.step(specs, steps)
            _reply_equals_outcomes(by_service, reply)
        assert reply.status == [0, 0] and reply.sim_time > 0
        # Alike robots are read in one gather per array (StateGather), also after a spawn moved
        # every id (its cached indices must follow), and robot by robot otherwise.
        for spawn in (False, True):
            if spawn:
                for name, client in zip(("sim_service", "sim_local"), clients):
                    client.spawn_entity("c", uri=RX200, namespace=f"/{name}/c", position=(-2.0, 0.0, 0.0))
            for specs, steps in [*alike, calls[0], calls[1]]:
                by_service = clients[0].step_robots(specs, steps=steps)
                reply = local.step(specs, steps)
                _reply_equals_outcomes(by_service, reply)
                assert (reply.stacked is not None) == (specs is not calls[1][0])  # calls[1]: frames differ
        # over the service, the same call answers the same StepReply
        over_ros = ServiceStepper(clients[1])
        for specs, steps in alike:
            a, b = over_ros.step(specs, steps), local.step(specs, 0)
            assert a.status == b.status == [0, 0]
            np.testing.assert_array_equal(a.stacked.position, b.stacked.position)
            np.testing.assert_array_equal(a.stacked.frame_positions, b.stacked.frame_positions)
        for specs, match in (([RobotStepSpec("a"), RobotStepSpec("a")], "more than once"),
                             ([RobotStepSpec(n) for n in "abcd"], "max_robots=3")):
            with pytest.raises(SimulationServiceError, match=match):
                clients[0].step_robots(specs, steps=1)
            with pytest.raises(SimulationServiceError, match=match) as refused:
                local.step(specs, 1)
            assert refused.value.service == "/sim_local/step_robots"
        with pytest.raises(SimulationServiceError, match="max_steps_per_call"):
            local.step([RobotStepSpec("a")], nodes[1].max_steps_per_call + 1)
        assert nodes[1].lock.acquire(timeout=1.0)  # every call released the node's lock, refused ones too
        nodes[1].lock.release()
    finally:
        ctx.try_shutdown()


def test_batch_interface_hashes_are_pinned() -> None:
    """The wire identity of the new services (changing a definition must be deliberate)."""
    assert type_hash("uniros_interfaces/srv/StepRobots") == (
        "RIHS01_832a6f4e288783fb858cfffa14aa047007735801d9c8a662217dc5fa324e7fe5")
    assert type_hash("uniros_interfaces/srv/GetNodeLoad") == (
        "RIHS01_ef840b7bba2526b70de56add0bfefcb2a155191f59804b3dfb7eb9995035cc3c")


@pytest.mark.slow
def test_her_sac_on_batched_sb3_vec_env() -> None:
    from stable_baselines3 import SAC, HerReplayBuffer
    from stable_baselines3.common.env_checker import check_env  # noqa: F401  (SB3 importable)

    from uniros.vec_env import make_batched_vec_env

    venv = make_batched_vec_env(ENV, 2, max_episode_steps=20)
    try:
        venv.seed(3)
        model = SAC("MultiInputPolicy", venv, replay_buffer_class=HerReplayBuffer,
                    replay_buffer_kwargs={"n_sampled_goal": 4, "goal_selection_strategy": "future"},
                    learning_starts=100, batch_size=32, train_freq=1, gradient_steps=1,
                    policy_kwargs={"net_arch": [32, 32]}, seed=0, verbose=0)
        model.learn(300)
        assert model.num_timesteps >= 300
        assert model.replay_buffer.size() > 0
        rewards = venv.env_method("compute_reward", np.zeros((5, 3)), np.zeros((5, 3)), [{}] * 5, indices=[1])
        assert rewards[0].shape == (5,) and np.all(rewards[0] == 0.0)
        assert venv.get_attr("robot_name", indices=0)[0].startswith("rx200_")
        assert venv.env_is_wrapped(gym.Wrapper) == [False, False]
    finally:
        venv.close()
