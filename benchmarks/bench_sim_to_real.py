"""Sim-to-real on stand-ins: train on RX200ReacherGoalSim-v0, evaluate the same model unchanged on
RX200ReacherGoalReal-v0 against each robot stand-in at real-time speed, print the success rates side
by side (the sim-to-real gap on this "robot").

1. ``uniros train RX200ReacherGoalSim-v0`` (the shipped HER + SAC config) for ``--steps`` steps into a
   run directory of a temporary folder;
2. ``uniros eval RUN_DIR RX200ReacherGoalSim-v0`` (lockstep, the simulated env);
3. for each stand-in, on a private Zenoh router on a free loopback port (never 7447):
   ``uniros-fake-robot --robot rx200`` (first-order joint lag, joint_states at 100 Hz) and the
   simulation node in real-time mode (``uniros-sim --play``), then
   ``uniros eval RUN_DIR --env RX200ReacherGoalReal-v0`` at the Real env's loop rate (wall clock).

    python benchmarks/bench_sim_to_real.py [--steps 6000] [--episodes 20] [--keep DIR]

Each stand-in is stopped by PID; the Real env talks to it only through ros2_control's interfaces.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from multiros.ros.processes import child_environment, private_context, stop_process, track_child, untrack_child

RX200_URI = "package://rx200_description/urdf/rx200.urdf.xacro?robot_name=rx200"
_RATE = re.compile(r"success rate ([0-9.]+)")


def _uniros(*args: str, env: dict[str, str] | None = None, cwd: Path, timeout: float) -> str:
    cmd = [sys.executable, "-m", "uniros.cli", *args]
    proc = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(args)} failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    return proc.stdout


def _success(output: str) -> float:
    rates = _RATE.findall(output)
    if not rates:
        raise RuntimeError(f"no success rate in:\n{output[-2000:]}")
    return float(rates[-1])


def _start_standin(kind: str, env: dict[str, str], cwd: Path) -> subprocess.Popen:
    if kind == "fake robot":
        argv = [sys.executable, "-m", "multiros.hardware.fake_robot", "--robot", "rx200", "--router", "none"]
    else:
        argv = [sys.executable, "-m", "multiros.sim.program", "--play", "--router", "none", "--log-level", "WARNING",
                "--robot", f"rx200={RX200_URI}"]
    return track_child(subprocess.Popen(argv + ["--owner-pid", str(os.getpid())], env=env, cwd=cwd,
                                        stdin=subprocess.DEVNULL))


def _wait_ready(ctx, proc: subprocess.Popen, timeout: float = 60.0) -> None:
    from multiros.ros import Node
    from multiros.ros.controller_manager import ControllerManagerClient

    node = Node(f"bench_probe_{os.getpid()}", context=ctx)
    try:
        ControllerManagerClient(node, "/rx200").wait_until_ready(timeout, proc)
    finally:
        node.destroy_node()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=6000, help="training steps on the simulated env")
    parser.add_argument("--episodes", type=int, default=20, help="evaluation episodes per side")
    parser.add_argument("--keep", type=Path, help="keep the run directory here instead of a temporary folder")
    args = parser.parse_args()

    work = Path(tempfile.mkdtemp(prefix="uniros_sim2real_"))
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    try:
        t0 = time.perf_counter()
        _uniros("train", "RX200ReacherGoalSim-v0", "--steps", str(args.steps), "--output", str(work), "--name", "run",
                "--no-video", "--no-progress", "--eval-episodes", "5", env=env, cwd=work, timeout=3600)
        train_s = time.perf_counter() - t0
        run = work / "run"
        rows = []
        t0 = time.perf_counter()
        sim = _success(_uniros("eval", "RX200ReacherGoalSim-v0", str(run), "--episodes", str(args.episodes),
                               env=env, cwd=work, timeout=1800))
        rows.append(("RX200ReacherGoalSim-v0 (lockstep)", sim, time.perf_counter() - t0))
        for kind in ("fake robot", "simulation node, real time"):
            ctx = private_context()
            child_env = {k: v for k, v in env.items() if not k.startswith(("ZENOH_", "UNIROS_ZENOH_"))}
            child_env.update(child_environment(ctx))
            proc = _start_standin(kind, child_env, work)
            try:
                _wait_ready(ctx, proc)
                t0 = time.perf_counter()
                real = _success(_uniros("eval", str(run), "--env", "RX200ReacherGoalReal-v0", "--episodes",
                                        str(args.episodes), env=child_env, cwd=work, timeout=3600))
                rows.append((f"RX200ReacherGoalReal-v0 on the {kind}", real, time.perf_counter() - t0))
            finally:
                stop_process(proc)
                untrack_child(proc)
                ctx.try_shutdown()
        print(f"trained {args.steps} steps on RX200ReacherGoalSim-v0 in {train_s:.0f} s; "
              f"{args.episodes} evaluation episodes per row, the same model file")
        print(f"{'env':<58} {'success':>8} {'gap vs sim':>11} {'eval s':>8}")
        for name, rate, secs in rows:
            print(f"{name:<58} {rate:>8.2f} {rate - sim:>+11.2f} {secs:>8.0f}")
        if args.keep:
            shutil.copytree(run, args.keep, dirs_exist_ok=True)
            print(f"run directory kept in {args.keep}")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
