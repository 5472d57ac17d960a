"""Fair service over rclpy: a quick client beside two clients flooding long steps, and a burst of calls.

Run in the venv ``.ci/rclpy`` makes (rclpy + Fast DDS from PyPI and the built interface packages)::

    .venv-rclpy/bin/python benchmarks/bench_rclpy_fairness.py [--calls 100] [--burst 200]

Starts ``uniros-sim --transport rclpy`` with an RX200 in a child process, then, each client a
plain rclpy node (nothing of uniros) in a process of its own:

* ``GetEntities`` latency of a third client, alone and while two other clients call
  ``StepSimulation(steps=100000)`` back to back (the goal: p95 <= 50 ms beside the flooders);
* how long each flooder's ``StepSimulation(100000)`` took meanwhile (the price of the turns);
* ``--burst N`` parallel ``GetSimulationState`` calls of one client, and how many were answered: a
  client with rclpy's default history (KEEP_LAST 10) and one with KEEP_ALL.

The figures share this machine's load of the moment (it may be busy): compare alone against
beside the flooders, measured in this one run. Traffic stays on localhost on a private domain.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
os.environ.setdefault("ROS_DOMAIN_ID", str(101 + os.getpid() % 100))
os.environ.setdefault("MUJOCO_GL", "egl")

RX200 = "rx200=package://rx200_description/urdf/rx200.urdf.xacro?robot_name=rx200"
SIM = "/mujoco_sim"


class Peer:
    """A plain rclpy node spun on a thread of its own."""

    def __init__(self, name: str) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        self.rclpy = rclpy
        self.context = rclpy.Context()
        rclpy.init(args=[], context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self.executor.spin, daemon=True)
        self._thread.start()

    def client(self, srv_type, name: str, timeout: float = 60.0, keep_all: bool = False):
        from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

        qos = QoSProfile(depth=10, history=HistoryPolicy.KEEP_ALL if keep_all else HistoryPolicy.KEEP_LAST,
                         reliability=ReliabilityPolicy.RELIABLE)  # KEEP_LAST 10: rclpy's default for services
        cli = self.node.create_client(srv_type, name, qos_profile=qos)
        if not cli.wait_for_service(timeout_sec=timeout):
            raise SystemExit(f"service {name} did not appear within {timeout:g} s")
        return cli

    @staticmethod
    def call(cli, request, timeout: float = 60.0):
        done = threading.Event()
        future = cli.call_async(request)
        future.add_done_callback(lambda _f: done.set())
        if not done.wait(timeout):
            cli.remove_pending_request(future)
            return None
        return future.result()

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=2.0)
        self.node.destroy_node()
        self.rclpy.try_shutdown(context=self.context)


def flood(seconds: float) -> None:
    """Child mode: call StepSimulation(100000) back to back for ``seconds``; print the durations (JSON)."""
    from simulation_interfaces.srv import StepSimulation

    peer = Peer(f"flooder_{os.getpid()}")
    cli = peer.client(StepSimulation, f"{SIM}/step_simulation")
    print("flooding", flush=True)
    durations = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        t0 = time.perf_counter()
        if peer.call(cli, StepSimulation.Request(steps=100000), timeout=120.0) is None:
            break
        durations.append(time.perf_counter() - t0)
    print(json.dumps(durations), flush=True)
    peer.close()


def _latencies(peer: Peer, cli, request, calls: int, gap: float) -> tuple[list[float], int]:
    out, lost = [], 0
    for _ in range(calls):
        t0 = time.perf_counter()
        if peer.call(cli, request, timeout=30.0) is None:
            lost += 1
        else:
            out.append(time.perf_counter() - t0)
        time.sleep(gap)
    return out, lost


def _summary(label: str, values: list[float], lost: int = 0) -> str:
    if not values:
        return f"{label}: no answer ({lost} lost)"
    ms = sorted(v * 1e3 for v in values)
    p95 = ms[min(len(ms) - 1, int(round(0.95 * (len(ms) - 1))))]
    return (f"{label}: n={len(ms)} median {statistics.median(ms):.1f} ms, p95 {p95:.1f} ms, max {ms[-1]:.1f} ms"
            + (f", {lost} unanswered in 30 s" if lost else ""))


def burst(peer: Peer, n: int, keep_all: bool) -> tuple[int, float]:
    """``n`` GetSimulationState calls of one client at once: (answered within 30 s, seconds taken). The client
    keeps rclpy's default history of answers (KEEP_LAST 10) or, ``keep_all``, every answer."""
    from simulation_interfaces.srv import GetSimulationState

    cli = peer.client(GetSimulationState, f"{SIM}/get_simulation_state", keep_all=keep_all)
    lock, done, answered = threading.Lock(), threading.Event(), [0]

    def on_done(_f) -> None:
        with lock:
            answered[0] += 1
            if answered[0] == n:
                done.set()

    t0 = time.perf_counter()
    for _ in range(n):
        cli.call_async(GetSimulationState.Request()).add_done_callback(on_done)
    done.wait(30.0)
    return answered[0], time.perf_counter() - t0


def _read(path: str) -> str:
    with open(path) as f:
        return f.read()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--calls", type=int, default=100, help="GetEntities calls per phase")
    parser.add_argument("--gap", type=float, default=0.02, help="seconds between two GetEntities calls")
    parser.add_argument("--burst", type=int, default=200, help="parallel calls of one client (0: skip)")
    parser.add_argument("--flood", type=float, default=None, help=argparse.SUPPRESS)  # child mode
    opts = parser.parse_args()
    if opts.flood is not None:
        flood(opts.flood)
        return
    from simulation_interfaces.srv import GetEntities

    bindir = os.path.dirname(sys.executable)
    log = tempfile.NamedTemporaryFile("w+", prefix="uniros-sim-", suffix=".log", delete=False)  # noqa: SIM115
    sim = subprocess.Popen([os.path.join(bindir, "uniros-sim"), "--transport", "rclpy", "--robot", RX200,
                            "--owner-pid", str(os.getpid())], stdout=log, stderr=subprocess.STDOUT,
                           stdin=subprocess.DEVNULL)
    flooders: list[subprocess.Popen] = []
    peer = None
    try:
        deadline = time.monotonic() + 120
        while "ready" not in _read(log.name):
            if sim.poll() is not None or time.monotonic() > deadline:
                raise SystemExit(f"uniros-sim did not start:\n{_read(log.name)[-2000:]}")
            time.sleep(0.1)
        peer = Peer("fairness_probe")
        cli = peer.client(GetEntities, f"{SIM}/get_entities")
        request = GetEntities.Request()
        _latencies(peer, cli, request, 10, 0.0)  # warm-up
        alone, lost_alone = _latencies(peer, cli, request, opts.calls, opts.gap)
        bursts = {keep_all: burst(peer, opts.burst, keep_all) for keep_all in (False, True)} if opts.burst else {}
        seconds = opts.calls * (opts.gap + 0.01) + 15
        flooders = [subprocess.Popen([sys.executable, __file__, "--flood", str(seconds)], stdout=subprocess.PIPE,
                                     text=True, stdin=subprocess.DEVNULL) for _ in range(2)]
        for f in flooders:
            assert f.stdout is not None
            if f.stdout.readline().strip() != "flooding":
                raise SystemExit("a flooder did not start")
        time.sleep(1.0)  # both flooders' first long calls under way
        beside, lost_beside = _latencies(peer, cli, request, opts.calls, opts.gap)
        steps: list[float] = []
        for f in flooders:
            out, _ = f.communicate(timeout=seconds + 180)
            steps += json.loads(out.strip().splitlines()[-1])
        print(_summary("GetEntities alone", alone, lost_alone))
        print(_summary("GetEntities beside two StepSimulation(100000) flooders", beside, lost_beside))
        if steps:
            print(f"flooders' StepSimulation(100000): n={len(steps)} median {statistics.median(steps):.2f} s, "
                  f"max {max(steps):.2f} s")
        for keep_all, (answered, took) in bursts.items():
            print(f"burst: {answered}/{opts.burst} parallel GetSimulationState calls of one client "
                  f"({'KEEP_ALL' if keep_all else 'default KEEP_LAST 10'} history) answered in {took:.2f} s")
    finally:
        if peer is not None:
            peer.close()
        for proc in [*flooders, sim]:
            if proc.poll() is None:
                proc.terminate()
                try:
                    proc.wait(10)
                except subprocess.TimeoutExpired:
                    proc.kill()
        log.close()
        os.unlink(log.name)


if __name__ == "__main__":
    main()
