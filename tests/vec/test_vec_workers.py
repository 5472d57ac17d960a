"""Vector envs whose envs step in worker processes (``multiros.envs.worker_vector``): the same
trajectories as one env and as the in-process batch whatever the number of workers, workers
stopped by PID, a killed worker named in an error, no growth per make/close, the SB3 form."""

from __future__ import annotations

import logging
import os
import signal
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import uniros
from multiros.envs.shm_exchange import PLAIN_INFO, InfoCodec, merge_infos
from multiros.envs.worker_vector import WorkerError, WorkerVectorEnv

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "envs"))
from golden_trajectories import CASES, HORIZON, SEEDS, _flat, actions_for, load  # noqa: E402

ENV = "RX200ReacherGoalSim-v0"

pytestmark = pytest.mark.multiprocess


def _row(obs, i):
    return {k: v[i] for k, v in obs.items()} if isinstance(obs, dict) else obs[i]


def _record(vec, case: str, seeds: tuple[int, ...]) -> list[dict[str, np.ndarray]]:
    """Each env's trajectory, as tests/envs/golden_trajectories.py records one env (SAME_STEP autoreset)."""
    n = vec.num_envs
    outs = [{"obs": [], "reward": [], "terminated": [], "truncated": [], "success": []} for _ in range(n)]
    obs, info = vec.reset(seed=list(seeds))
    for i in range(n):
        outs[i]["obs"].append(_flat(_row(obs, i)))
        outs[i]["success"].append(bool(info["is_success"][i]) if "is_success" in info else False)
    acts = np.stack([actions_for(vec.single_action_space, case, s) for s in seeds], axis=1)
    for a in acts:
        obs, reward, terminated, truncated, info = vec.step(a)
        for i in range(n):
            ended = bool(terminated[i] or truncated[i])
            o = outs[i]
            if ended:
                o["obs"].append(_flat(info["final_obs"][i]))
                o["success"].append(bool(info["final_info"]["is_success"][i]))
            else:
                o["obs"].append(_flat(_row(obs, i)))
                o["success"].append(bool(info["is_success"][i]))
            o["reward"].append(float(reward[i]))
            o["terminated"].append(bool(terminated[i]))
            o["truncated"].append(bool(truncated[i]))
            if ended:
                o["obs"].append(_flat(_row(obs, i)))
                o["success"].append(bool(info["is_success"][i]))
    return [{k: np.asarray(v) for k, v in o.items()} for o in outs]


def _workers_vec(env_id: str, n: int, workers: int, in_parent: bool = False, **kwargs):
    return uniros.make_vec(env_id, n, max_episode_steps=HORIZON, vector_kwargs={
        "autoreset_mode": AutoresetMode.SAME_STEP, "workers": workers, "in_parent": in_parent}, **kwargs)


#: The two layouts of the shares: worker processes only, and one worker plus this process's share.
LAYOUTS = [pytest.param({"workers": 2}, id="2-workers"),
           pytest.param({"workers": 1, "in_parent": True}, id="1-worker+parent")]


def _check_golden(case: str, got: dict[str, np.ndarray], seed: int) -> None:
    golden = load()
    for key, value in got.items():
        want = golden[f"{case}/{seed}/{key}"]
        assert value.shape == want.shape, (case, seed, key)
        np.testing.assert_allclose(value, want, atol=1e-9, rtol=0, err_msg=f"{case} seed {seed} {key}")


def _step_alike(ours, theirs, *, seed: int, steps: int) -> Iterator[tuple[int, tuple, tuple]]:
    """Step two vector envs of 3 RX200 envs with the same random actions (``default_rng(seed)``),
    assert each step's observations equal key by key, and yield ``(t, ours' step, theirs' step)``
    for the test to compare the rest."""
    rng = np.random.default_rng(seed)
    for t in range(steps):
        actions = rng.uniform(-1, 1, (3, 5)).astype(np.float32)
        a, b = ours.step(actions), theirs.step(actions)
        for key in a[0]:
            np.testing.assert_array_equal(a[0][key], b[0][key])
        yield t, a, b


# Every golden case through two workers: the tasks' infos differ (and so do the layouts InfoCodec
# learns), the in-process batch replays the same twelve (tests/envs/test_golden_trajectories.py).
# All twelve take about 10 s; one runs in the fast suite.
WORKER_CASES = tuple(c[0] for c in CASES)


@pytest.mark.parametrize(("case", "env_id", "kwargs"),
                         [pytest.param(*c, marks=() if c[0] == "rx200_reach_goal" else pytest.mark.slow)
                          for c in CASES if c[0] in WORKER_CASES])
def test_workers_replay_the_single_env_recordings(case: str, env_id: str, kwargs: dict) -> None:
    """Every shipped task, two worker processes of one env each: each env returns what one env alone
    returned when the golden trajectories were recorded (to 1e-9)."""
    vec = _workers_vec(env_id, len(SEEDS), 2, **kwargs)
    try:
        assert isinstance(vec, WorkerVectorEnv) and vec.num_workers == 2
        for seed, got in zip(SEEDS, _record(vec, case, SEEDS)):
            _check_golden(case, got, seed)
    finally:
        vec.close()


def test_env_i_is_the_same_whatever_the_number_of_workers() -> None:
    """Env i of 5 runs the same trajectory in this process, in 2 workers (uneven shares) and in 5."""
    case, seeds = "rx200_reach_goal", (3, 4, 3, 4, 3)
    vec = uniros.make_vec(ENV, 5, vectorization_mode="batched", max_episode_steps=HORIZON,
                          vector_kwargs={"autoreset_mode": AutoresetMode.SAME_STEP, "num_nodes": 1})
    try:
        expected = _record(vec, case, seeds)
    finally:
        vec.close()
    for workers in (2, 5, "1+parent"):
        vec = _workers_vec(ENV, 5, 1, in_parent=True) if workers == "1+parent" else _workers_vec(ENV, 5, workers)
        try:
            if workers == "1+parent":  # this process steps the first share
                assert vec.local_rows == (0, 2) and vec.rows == [(2, 5)] and len(vec.pids) == 1
            else:
                assert vec.rows == ([(0, 2), (2, 5)] if workers == 2 else [(i, i + 1) for i in range(5)])
            for i, (got, want) in enumerate(zip(_record(vec, case, seeds), expected)):
                for key in want:
                    np.testing.assert_array_equal(got[key], want[key], err_msg=f"workers={workers} env {i} {key}")
                _check_golden(case, got, seeds[i])
        finally:
            vec.close()


@pytest.mark.parametrize("layout", LAYOUTS)
def test_next_step_autoreset_reset_mask_and_sub_env_access(layout: dict) -> None:
    """NEXT_STEP autoreset, ``reset_mask`` split over the shares, int seeds, ``call``/``get_attr``/
    ``set_attr``, errors of a worker raised here with their type: as the in-process batch does."""
    ours = uniros.make_vec(ENV, 3, max_episode_steps=4, vector_kwargs=layout)
    theirs = uniros.make_vec(ENV, 3, vectorization_mode="batched", max_episode_steps=4,
                             vector_kwargs={"num_nodes": 1})
    try:
        assert ours.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
        assert ours.observation_space == theirs.observation_space and ours.action_space == theirs.action_space
        for vec in (ours, theirs):
            vec.reset(seed=5)
        for t, a, b in _step_alike(ours, theirs, seed=2, steps=11):
            for x, y in zip(a[1:4], b[1:4]):
                np.testing.assert_array_equal(x, y)
            assert a[4].keys() == b[4].keys()
            for key in a[4]:
                np.testing.assert_array_equal(a[4][key], b[4][key])
            if t == 5:
                mask = np.array([False, False, True])
                ra, rb = ours.reset(options={"reset_mask": mask}), theirs.reset(options={"reset_mask": mask})
                for key in ra[0]:
                    np.testing.assert_array_equal(ra[0][key], rb[0][key])
        names = ours.get_attr("robot_name")
        assert len(names) == 3 and len(set(names)) == 3
        assert ours.call_at([2, 0], "compute_reward", np.zeros(3), np.ones(3), {}) == [
            theirs.envs[2].compute_reward(np.zeros(3), np.ones(3), {})] * 2
        ours.set_attr("test_marker", [1, 2, 3])
        assert ours.get_attr("test_marker") == (1, 2, 3)
        with pytest.raises(AttributeError, match="no_such_attribute"):
            ours.get_attr("no_such_attribute")
        with pytest.raises(ValueError, match="actions of shape"):
            ours.step(np.zeros((2, 5), np.float32))
        assert [load["robots"] for load in ours.node_loads()] == [1, 2]
    finally:
        ours.close()
        theirs.close()


def _gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return False


@pytest.mark.parametrize("layout", LAYOUTS)
def test_close_stops_the_workers_by_pid_and_frees_the_shared_memory(layout: dict) -> None:
    vec = uniros.make_vec(ENV, 2, vector_kwargs=layout)
    pids, shm = vec.pids, Path("/dev/shm") / vec._workers.shared.name.lstrip("/")
    assert len(set(pids)) == layout["workers"] and os.getpid() not in pids and shm.exists()
    local = vec._workers.local
    vec.close()
    assert all(_gone(pid) for pid in pids)  # exited and reaped
    assert not shm.exists() and vec.pids == []
    assert local is None or local.vec is None  # the share stepped here is closed too
    with pytest.raises(WorkerError, match="closed"):
        vec.step(np.zeros((2, 5), np.float32))


def test_a_killed_worker_is_named_at_once() -> None:
    vec = uniros.make_vec(ENV, 2, vector_kwargs={"workers": 2, "timeout_sec": 5.0})
    try:
        vec.reset(seed=0)
        vec.step(np.zeros((2, 5), np.float32))
        victim = vec.pids[1]
        os.kill(victim, signal.SIGKILL)
        start = time.monotonic()
        with pytest.raises(WorkerError, match=rf"worker 1 \(pid {victim}, envs 1 to 1\) exited with code -9"):
            vec.step(np.zeros((2, 5), np.float32))
        assert time.monotonic() - start < 5.0  # seen by the closed socket, not by the timeout
        with pytest.raises(WorkerError, match="close this vector env"):
            vec.reset()
    finally:
        pids = vec.pids
        vec.close()
    assert all(_gone(pid) for pid in pids)


def test_a_worker_that_stops_answering_is_named_after_the_timeout() -> None:
    # timeout_sec also bounds each worker's own node calls (the reset and step before the stop): not too tight
    vec = uniros.make_vec(ENV, 2, vector_kwargs={"workers": 2, "timeout_sec": 2.0, "spin_wait_sec": 0.0})
    victim = None
    try:
        vec.reset(seed=0)
        vec.step(np.zeros((2, 5), np.float32))
        victim = vec.pids[0]
        os.kill(victim, signal.SIGSTOP)  # alive, its socket open: only the timeout can tell
        start = time.monotonic()
        # The bound is the workers' own (timeout_sec) and 5 s: a worker's node call times out first.
        with pytest.raises(WorkerError, match=rf"worker 0 \(pid {victim}\) did not answer a step within 7 s"):
            vec.step(np.zeros((2, 5), np.float32))
        assert time.monotonic() - start >= 7.0
        with pytest.raises(WorkerError, match="close this vector env"):
            vec.step(np.zeros((2, 5), np.float32))
    finally:
        if victim is not None:
            os.kill(victim, signal.SIGCONT)
        pids = vec.pids
        vec.close()
    assert all(_gone(pid) for pid in pids)


def test_a_worker_that_cannot_start_says_why() -> None:
    with pytest.raises(WorkerError, match=r"failed to start: TypeError: .*'no_such_knob'.*workers': 0"):
        uniros.make_vec(ENV, 2, vector_kwargs={"workers": 2}, no_such_knob=1)


def _census() -> tuple[int, int]:
    fds = len(os.listdir("/proc/self/fd"))
    children = len(Path(f"/proc/{os.getpid()}/task/{os.getpid()}/children").read_text().split())
    return fds, children


@pytest.mark.parametrize("layout", LAYOUTS)
def test_make_close_cycles_do_not_grow(layout: dict) -> None:
    blocks: list[str] = []

    def cycle() -> None:
        vec = _workers_vec(ENV, 2, layout["workers"], layout.get("in_parent", False))
        blocks.append(vec.shared_memory_name)
        assert Path("/dev/shm", vec.shared_memory_name).exists()
        vec.reset(seed=1)
        vec.step(np.zeros((2, 5), np.float32))
        vec.close()

    cycle()  # first-use imports and caches
    before = _census()
    for _ in range(3):
        cycle()
    fds, children = _census()
    assert fds <= before[0] and children == before[1]  # the resource tracker, started once, stays
    # only our own blocks are counted: other tests and sessions on this machine make theirs at any time
    assert len(set(blocks)) == 4 and not [b for b in blocks if Path("/dev/shm", b).exists()]


@pytest.mark.parametrize("layout", LAYOUTS)
def test_worker_stats_count_the_steps_and_their_time(layout: dict) -> None:
    vec = _workers_vec(ENV, 3, layout["workers"], layout.get("in_parent", False))
    try:
        vec.reset(seed=0)
        assert [s["steps"] for s in vec.worker_stats()] == [0.0, 0.0]
        began = time.perf_counter()
        for _ in range(3):
            vec.step(np.zeros((3, 5), np.float32))
        wall = time.perf_counter() - began
        stats = vec.worker_stats()
        assert [s["steps"] for s in stats] == [3.0, 3.0]
        assert all(0.0 < s["busy_seconds"] < wall for s in stats)
        here = stats[0] if layout.get("in_parent") else None  # this process's share, if it steps one
        for s in stats:
            if s is here:  # no answers to send; its wait is for the workers' answers within these steps
                assert s["answer_seconds"] == 0.0 and 0.0 < s["wait_seconds"] < wall
            else:  # a worker sent 3 step answers and waited for every order
                assert s["answer_seconds"] > 0.0 and s["wait_seconds"] > 0.0
    finally:
        vec.close()


def test_by_default_this_process_steps_a_share_and_a_worker_each_other_core(monkeypatch) -> None:
    """A share per core: K cores, K - 1 worker processes and this process's share; one core, or nodes
    placed by hand, all in this process."""
    import multiros.envs.worker_layout as worker_layout

    monkeypatch.setattr(worker_layout, "default_num_nodes", lambda n: min(n, 2))
    assert worker_layout.default_layout(8) == (1, True)
    assert worker_layout.default_layout(1) == (0, False)
    assert worker_layout.default_layout(8, options={"num_nodes": 2}) == (0, False)
    assert worker_layout.default_layout(8, "existing") == (0, False)
    monkeypatch.setattr(worker_layout, "default_num_nodes", lambda n: min(n, 16))
    assert worker_layout.default_layout(128) == (15, True)


def test_process_mode_by_default_is_a_worker_per_node_and_none_in_this_process(monkeypatch) -> None:
    """``sim_mode="process"``: the nodes (one per core, or ``num_nodes``) are worker processes, none in
    this one; a node on a wire of the caller's or with a viewer, placed by hand, or a ``num_nodes``
    that is no count of nodes: this process calls them over Zenoh (``workers=0``)."""
    import multiros.envs.worker_layout as worker_layout

    monkeypatch.setattr(worker_layout, "default_num_nodes", lambda n: min(n, 2))
    assert worker_layout.default_layout(8, "process") == (2, False)
    assert worker_layout.default_layout(1, "process") == (1, False)  # one core or one env: still a child process
    assert worker_layout.default_layout(8, "process", {"num_nodes": 4}) == (4, False)
    for options, env_kwargs in [({}, {"transport": "zenoh"}), ({}, {"transport": "rclpy"}), ({}, {"gui": True}),
                                ({"node_name": "sim"}, {}), ({"num_nodes": 9}, {}), ({"num_nodes": "2"}, {}),
                                ({"num_nodes": 0}, {})]:
        assert worker_layout.default_layout(8, "process", options, env_kwargs) == (0, False), (options, env_kwargs)
    assert worker_layout.default_layout(8, "process", {}, {"transport": None, "gui": False}) == (2, False)
    monkeypatch.setenv("UNIROS_TRANSPORT", "rclpy")  # the wire a process-mode node would take
    assert worker_layout.default_layout(8, "process") == (0, False)


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"workers": 1, "in_parent": True, "env_kwargs": {"sim_mode": "process"}},
     r"puts every node in a child process; in_parent would step a share"),
    ({"workers": 1, "env_kwargs": {"sim_mode": "existing"}}, r"sim_mode='existing' reaches nodes elsewhere"),
    ({"workers": 1, "env_kwargs": {"sim_mode": "process", "transport": "zenoh"}},
     r"transport='zenoh' needs workers=0"),
    ({"workers": 1, "env_kwargs": {"sim_mode": "process", "gui": True}}, r"gui=True needs workers=0"),
    ({"workers": 1, "batch_options": {"num_nodes": 2}, "env_kwargs": {"sim_mode": "process"}},
     r"one node in each, so num_nodes counts all the nodes .*: num_nodes=2 and workers=1 differ"),
    ({"workers": 1, "batch_options": {"connect_kwargs": {"transport": "zenoh"}}, "env_kwargs": {"sim_mode": "process"}},
     r"\['connect_kwargs'\] place nodes by hand: use workers=0"),
    ({"batch_options": {"num_nodes": 3}, "env_kwargs": {"sim_mode": "process"}},
     r"num_nodes must be an integer from 1 to num_envs \(2\), got 3"),
])
def test_process_mode_layouts_that_do_not_fit_are_refused_before_any_process_starts(kwargs: dict, match: str) -> None:
    before = _census()
    with pytest.raises(ValueError, match=match):
        WorkerVectorEnv(ENV, 2, **kwargs)
    assert _census() == before


@pytest.mark.parametrize(("workers", "in_parent", "match"), [
    (2, True, r"from 1 to num_envs \(2\) less one \(this process steps a share: in_parent\), got 2"),
    (0, False, r"from 1 to num_envs \(2\), got 0"),
    ("1", True, r"got '1'"),
])
def test_worker_counts_that_do_not_fit_are_refused_before_any_process_starts(workers, in_parent, match) -> None:
    before = _census()
    with pytest.raises(ValueError, match=match):
        WorkerVectorEnv(ENV, 2, workers=workers, in_parent=in_parent)
    assert _census() == before


def _assert_step_alike(x, y, seed: int, steps: int = 5) -> None:
    """Two vector envs of the same envs, reset with ``seed`` and given the same actions, observe alike."""
    a, b = x.reset(seed=seed)[0], y.reset(seed=seed)[0]
    for i in range(steps):
        act = np.full(x.action_space.shape, 0.1 * i, np.float32)
        a, b = x.step(act)[0], y.step(act)[0]
    for key in a:
        np.testing.assert_array_equal(a[key], b[key])


def _thread_cores(pid: int) -> set[frozenset[int]]:
    """The CPU affinity of every thread of process ``pid`` (one that ends meanwhile left out)."""
    out = set()
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            out.add(frozenset(os.sched_getaffinity(int(tid))))
        except ProcessLookupError:
            pass
    return out


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity") or len(os.sched_getaffinity(0)) < 2,
                    reason="needs CPU affinity and two cores")
@pytest.mark.parametrize("layout", [{"workers": 1, "in_parent": True}, {"workers": 2}])
def test_pinned_workers_each_run_on_a_core_of_their_own(layout: dict, monkeypatch) -> None:
    """``pin_workers``: worker k and every thread it has on one core (the first left to this process's
    share with ``in_parent``), numpy's BLAS threads included (started at import: the suite's
    OMP_NUM_THREADS=1 is lifted for these workers), this process not pinned; the envs step alike."""
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    cores = sorted(os.sched_getaffinity(0))
    vec = WorkerVectorEnv(ENV, 4, pin_workers=True, **layout)
    free = WorkerVectorEnv(ENV, 4, **layout)
    try:
        first = 1 if layout.get("in_parent") else 0
        assert vec.worker_cores == cores[first:first + layout["workers"]]
        for pid, core in zip(vec.pids, vec.worker_cores):
            assert _thread_cores(pid) == {frozenset({core})}
        assert free.worker_cores == [None] * layout["workers"]
        assert all(_thread_cores(pid) == {frozenset(cores)} for pid in free.pids)
        assert sorted(os.sched_getaffinity(0)) == cores
        _assert_step_alike(vec, free, seed=3)
    finally:
        vec.close()
        free.close()


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="needs CPU affinity")
def test_pinning_more_shares_than_cores_or_a_non_bool_is_refused_before_any_process_starts(monkeypatch) -> None:
    import multiros.envs.worker_layout as worker_layout

    before = _census()
    cores = len(os.sched_getaffinity(0))
    with pytest.raises(ValueError, match=rf"{cores} worker\(s\) and this process need {cores + 1} cores"):
        WorkerVectorEnv(ENV, cores + 1, workers=cores, in_parent=True, pin_workers=True)
    with pytest.raises(ValueError, match=r"pin_workers must be true or false, got 'no'"):
        WorkerVectorEnv(ENV, 2, workers=1, pin_workers="no")
    with pytest.raises(ValueError, match=r"pin_workers must be true or false, got 'yes'"):
        uniros.make_vec(ENV, 2, vector_kwargs={"pin_workers": "yes"})
    from uniros.vec_env import make_batched_vec_env

    with pytest.raises(ValueError, match=r"pin_workers must be true or false, got 1"):
        make_batched_vec_env(ENV, 2, pin_workers=1)
    monkeypatch.delattr(os, "sched_setaffinity")
    with pytest.raises(ValueError, match=r"needs CPU affinity"):
        worker_layout.worker_cores(1)
    assert _census() == before


@pytest.mark.parametrize(("level", "shown"), [(logging.INFO, True), (logging.WARNING, False)])
def test_workers_log_at_the_level_of_this_process_node_loggers(capfd, level: int, shown: bool) -> None:
    """A worker's node logs what this process's node loggers would (its level passed as a node started
    for an env gets it): the INFO line of two robots on one node sharing TF frames, or nothing."""
    ros = logging.getLogger("ros")
    old = ros.level
    ros.setLevel(level)
    try:
        WorkerVectorEnv(ENV, 2, workers=1).close()
    finally:
        ros.setLevel(old)
    err = capfd.readouterr().err
    assert ("[INFO] [ros.mujoco_sim]: entity " in err and "are already published by entity" in err) is shown, err


def test_both_sides_poll_before_they_sleep_only_where_each_share_has_a_core(monkeypatch) -> None:
    """``spin_wait_sec``: by default the workers poll ``SPIN_WAIT_SEC`` for this process's next order
    where the shares fit the cores, and this process polls for their answers where it also steps a
    share; not the parent of process mode (no share: it waits on a core a worker needs) nor with more
    shares than cores; a value given is checked and goes to both sides; the envs step alike with it
    or without."""
    import multiros.envs.spin_wait as spin_wait

    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1}, raising=False)
    assert spin_wait._spin_wait(None, 2, True) == spin_wait.SPIN_WAIT_SEC
    assert spin_wait._spin_wait(None, 3, True) == 0.0  # more shares than cores
    assert spin_wait._spin_wait(None, 2, False) == 0.0  # no share here: the parent waits on a core a worker needs
    assert spin_wait._spin_wait(0, 2, True) == 0.0 and spin_wait._spin_wait(0.001, 3, False) == 0.001
    process = uniros.make_vec(ENV, 2, sim_mode="process")  # 2 nodes, 2 workers, no share here
    try:
        assert (process.spin_wait_sec, process.worker_spin_wait_sec) == (0.0, spin_wait.SPIN_WAIT_SEC)
    finally:
        process.close()
    for bad in (-1e-6, 0.5, "0.001", True):
        with pytest.raises(ValueError, match="spin_wait_sec must be a number of seconds from 0 to 0.01"):
            spin_wait._spin_wait(bad, 2, True)
    monkeypatch.undo()
    with pytest.raises(ValueError, match="spin_wait_sec must be"):
        uniros.make_vec(ENV, 2, vector_kwargs={"workers": 1, "spin_wait_sec": -1})
    spun = WorkerVectorEnv(ENV, 3, workers=1, in_parent=True, spin_wait_sec=0.002)
    slept = WorkerVectorEnv(ENV, 3, workers=1, in_parent=True, spin_wait_sec=0)
    try:
        assert (spun.spin_wait_sec, slept.spin_wait_sec) == (0.002, 0.0)
        assert (spun.worker_spin_wait_sec, slept.worker_spin_wait_sec) == (0.002, 0.0)
        _assert_step_alike(spun, slept, seed=5)
    finally:
        spun.close()
        slept.close()


def test_a_share_that_waits_for_a_core_sleeps_at_once(monkeypatch) -> None:
    """Spin-then-block stands down beside other programs: once this process's share has waited for a
    core more than ``QUEUED_TO_SPIN`` per step, it no longer polls for the workers' answers (it sleeps
    at once), and polls again once the waits are gone; the steps go on alike."""
    import multiros.envs.worker_vector as wv
    from multiros.envs.spin_wait import QUEUED_TO_SPIN

    spins: list[float] = []
    real_spin = wv._spin  # the parent's poll, patched where WorkerVectorEnv looks it up
    monkeypatch.setattr(wv, "_spin", lambda poller, seconds: spins.append(seconds) or real_spin(poller, seconds))
    vec = WorkerVectorEnv(ENV, 2, workers=1, in_parent=True, spin_wait_sec=0.001)
    try:
        vec.reset(seed=0)
        queued = vec._workers.local.queued
        queued.sample = lambda: None  # hold the mean where the test puts it
        for per_step, polled in ((0.0, 1), (2 * QUEUED_TO_SPIN, 0), (0.0, 1)):
            queued.per_step = per_step
            spins.clear()
            obs = vec.step(np.zeros((2, 5), np.float32))[0]
            assert spins == [0.001] * polled, per_step
            assert np.isfinite(obs["observation"]).all()
    finally:
        vec.close()


@pytest.mark.skipif(not Path("/proc/thread-self/schedstat").exists(), reason="Linux schedstat only")
def test_run_queue_delay_counts_the_time_a_thread_waits_for_its_core(monkeypatch) -> None:
    """``RunQueueDelay`` reads the kernel's wait of this thread (not its CPU time): pinned to one core
    beside two busy processes pinned there too, 0.1 s of this thread's work waits for the core about
    twice that; where the file is missing it stays 0 and says nothing."""
    import subprocess

    from multiros.envs.spin_wait import RunQueueDelay

    core = min(os.sched_getaffinity(0))
    before = os.sched_getaffinity(0)
    parent = os.getpid()  # the children stop by themselves within 60 s, or when this process is gone
    code = (f"import os, sys, time; os.sched_setaffinity(0, {{{core}}}); print(flush=True)\n"
            "sys.stdin.readline() or exit()\n"
            f"end = time.monotonic() + 60\nwhile time.monotonic() < end and os.getppid() == {parent}: pass")
    busy = [subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
            for _ in range(2)]
    delay = RunQueueDelay()
    try:
        for proc in busy:  # pinned, then spinning
            assert proc.stdout.readline() == "\n"
            proc.stdin.write("go\n")
            proc.stdin.flush()
        os.sched_setaffinity(0, {core})
        delay.sample()
        cpu = time.thread_time()
        while time.thread_time() - cpu < 0.1:  # 0.1 s of this thread's CPU, sharing the core
            pass
        delay.sample()
        waited = delay.per_step / RunQueueDelay.WEIGHT
        assert waited >= 1.3 * 0.1, waited
    finally:
        os.sched_setaffinity(0, before)
        for proc in busy:
            proc.kill()
            proc.wait(timeout=10)
        delay.close()
    missing = RunQueueDelay()
    real_open = os.open

    def no_proc(path, *args):
        if str(path).startswith("/proc/"):
            raise FileNotFoundError(path)
        return real_open(path, *args)

    monkeypatch.setattr(os, "open", no_proc)
    missing.sample()
    missing.sample()
    assert missing.per_step == 0.0


def test_an_interrupted_step_breaks_the_env_instead_of_reading_the_wrong_answers() -> None:
    """Ctrl-C in the middle of a step (here: this process's share raises KeyboardInterrupt) leaves the
    worker's answer unread; the next request says so instead of reading that answer as its own."""
    vec = WorkerVectorEnv(ENV, 2, workers=1, in_parent=True)
    try:
        vec.reset(seed=0)
        share = vec._workers.local

        def interrupted() -> None:
            raise KeyboardInterrupt

        share.step = interrupted
        with pytest.raises(KeyboardInterrupt):
            vec.step(np.zeros((2, 5), np.float32))
        with pytest.raises(WorkerError, match=r"interrupted \(KeyboardInterrupt\) during a step"):
            vec.reset(seed=1)
    finally:
        vec.close()


def test_an_error_of_the_share_stepped_here_keeps_the_workers_in_step() -> None:
    """A bad action in this process's share raises here once the worker has answered that step: the
    next steps' answers are their own, and the envs go on."""
    vec = uniros.make_vec(ENV, 2, vector_kwargs={"workers": 1, "in_parent": True, "timeout_sec": 5.0})
    try:
        vec.reset(seed=0)
        bad = np.zeros((2, 5), np.float32)
        bad[0, 0] = np.nan  # env 0: this process's share
        with pytest.raises(Exception, match="NaN"):
            vec.step(bad)
        for _ in range(3):
            obs, reward, terminated, truncated, info = vec.step(np.zeros((2, 5), np.float32))
        assert obs["observation"].shape == (2, 18) and np.isfinite(obs["observation"]).all()
        assert info["_is_success"].all()
        assert [s["steps"] for s in vec.worker_stats()] == [3.0, 4.0]  # the worker stepped the bad one too
    finally:
        vec.close()


def test_merge_infos_fills_what_a_worker_lacks() -> None:
    """As gymnasium's _add_info env by env: zeros / None and False masks where a worker has no key."""
    a = {"is_success": np.array([True, False]), "_is_success": np.array([True, True])}
    b = {"is_success": np.array([1.0]), "_is_success": np.array([True]),
         "final_info": {"x": np.array([2]), "_x": np.array([True])}, "_final_info": np.array([True])}
    out = merge_infos([(0, a), (2, b)], 3)
    np.testing.assert_array_equal(out["is_success"], [True, False, True])
    np.testing.assert_array_equal(out["_final_info"], [False, False, True])
    np.testing.assert_array_equal(out["final_info"]["x"], [0, 0, 2])
    np.testing.assert_array_equal(out["final_info"]["_x"], [False, False, True])
    assert merge_infos([(0, a)], 2) == a


def test_merge_infos_of_alike_workers_is_the_general_merge() -> None:
    """The quick merge of a usual step (same keys and dtypes in every worker) gives what the general
    merge gives, whatever order the parts come in; a dtype that differs goes the general way."""
    from multiros.envs.shm_exchange import _merge, _merge_alike

    a = {"is_success": np.array([0.0, 1.0]), "_is_success": np.array([True, True])}
    b = {"is_success": np.array([1.0, 0.0, 1.0]), "_is_success": np.array([True, False, True])}
    general = _merge([(0, 2, a), (2, 3, b)], 5)
    for parts in ([(0, a), (2, b)], [(2, b), (0, a)]):
        out = merge_infos(parts, 5)
        assert list(out) == list(general)
        for key in general:
            assert out[key].dtype == general[key].dtype
            np.testing.assert_array_equal(out[key], general[key])
    assert _merge_alike([(0, a), (2, b)], 5) is not None  # the quick way was taken
    c = {"is_success": np.array([1, 0, 1]), "_is_success": np.array([True, True, True])}  # ints, not floats
    out = merge_infos([(0, a), (2, c)], 5)
    np.testing.assert_array_equal(out["is_success"], [0.0, 1.0, 1.0, 0.0, 1.0])
    nested = {**b, "final_info": {"x": np.array([1, 2, 3])}}
    scalar = {"is_success": np.array(1.0), "_is_success": np.array([True, True, True])}
    for other in (c, nested, scalar, {}, dict(reversed(list(b.items())))):
        assert _merge_alike([(0, a), (2, other)], 5) is None, other  # the general merge's cases


def test_step_infos_travel_as_raw_bytes_once_their_layout_is_known() -> None:
    """InfoCodec, both ends of a worker's pipe: an info of numeric arrays packs to its bytes once a
    pickled one taught the layout; the parent reads it back into fresh writable arrays; any other
    info (nested, objects, another key or shape) is left to pickle; bytes that do not fit are refused."""
    worker, parent = InfoCodec(), InfoCodec()
    info = {"is_success": np.array([0.0, 1.0]), "_is_success": np.array([True, False])}
    assert worker.pack(info) is None  # nothing learnt yet: this one goes pickled, and both sides learn it
    worker.learn(info)
    parent.learn(info)
    data = worker.pack({"is_success": np.array([1.0, 1.0]), "_is_success": np.array([True, True])})
    assert data is not None and data[:1] == PLAIN_INFO
    first, second = parent.unpack(data), parent.unpack(data)
    assert list(first) == ["is_success", "_is_success"]
    assert all(value.flags.aligned and value.flags.writeable for value in first.values())
    assert first["is_success"].dtype == np.float64 and first["_is_success"].dtype == np.bool_
    np.testing.assert_array_equal(first["is_success"], [1.0, 1.0])
    first["is_success"][0] = 5.0  # writable, and each step's arrays are its own
    assert second["is_success"][0] == 1.0
    for other in ({"is_success": np.array([0.0, 1.0]), "_is_success": np.array([True, False]),
                   "final_info": {"x": np.array([1, 2])}},
                  {"is_success": np.array([0.0, 1.0, 1.0]), "_is_success": np.array([True, False, True])},
                  {"is_success": np.array([0, 1]), "_is_success": np.array([True, False])},
                  {"is_success": np.array([None, None]), "_is_success": np.array([True, False])},
                  {"is_success": 1.0, "_is_success": np.array([True, False])}):
        assert worker.pack(other) is None
    with pytest.raises(ValueError, match="makes"):
        parent.unpack(data[:-1])
    # out of step (a layout one side learnt and the other not): refused even where the sizes agree
    swapped = {"is_reached": np.array([1.0, 1.0]), "_is_reached": np.array([True, True])}
    ahead = InfoCodec()
    ahead.learn(info)
    ahead.learn(swapped)
    other = ahead.pack(swapped)
    assert other is not None and len(other) == len(data)
    with pytest.raises(ValueError, match="layout"):
        parent.unpack(other)
    with pytest.raises(ValueError, match="before any came pickled"):
        InfoCodec().unpack(data)
    worker.learn({"final_info": {}})  # a nested info went pickled: no raw bytes until a plain one goes
    assert worker.pack(info) is None


def test_sb3_worker_vec_env_equals_the_in_process_one() -> None:
    """``make_batched_vec_env`` in worker processes (its default on several cores) and in this
    process: same observations, rewards, dones, terminal observations and TimeLimit flags."""
    from uniros.vec_env import BatchedVecEnv, WorkerVecEnv, make_batched_vec_env

    ours = make_batched_vec_env(ENV, 3, workers=2, max_episode_steps=5)
    theirs = make_batched_vec_env(ENV, 3, workers=0, max_episode_steps=5)
    try:
        assert isinstance(ours, WorkerVecEnv) and isinstance(theirs, BatchedVecEnv)
        for venv in (ours, theirs):
            venv.seed(9)
        oa, ob = ours.reset(), theirs.reset()
        for key in oa:
            np.testing.assert_array_equal(oa[key], ob[key])
        for _, a, b in _step_alike(ours, theirs, seed=4, steps=12):
            np.testing.assert_array_equal(a[1], b[1])
            np.testing.assert_array_equal(a[2], b[2])
            for ia, ib in zip(a[3], b[3]):
                assert ia.keys() == ib.keys()
                assert ia["TimeLimit.truncated"] == ib["TimeLimit.truncated"]
                assert ia["is_success"] == ib["is_success"]
                if "terminal_observation" in ib:
                    for key in ib["terminal_observation"]:
                        np.testing.assert_array_equal(ia["terminal_observation"][key], ib["terminal_observation"][key])
        assert ours.env_method("compute_reward", np.zeros((4, 3)), np.zeros((4, 3)), [{}] * 4, indices=[1])[0].shape \
            == (4,)
        assert ours.get_attr("robot_name", indices=0)[0].startswith("rx200_")
    finally:
        pids = ours.pids
        ours.close()
        theirs.close()
    assert all(_gone(pid) for pid in pids)
