"""A nominal and a sim-to-real (randomised) reach policy on the stand-in robot's reality gap.

Issue 51's first goal: on ``uniros-fake-robot --gap hard`` (latency, lag, backlash, droop of the
shoulder and elbow, calibration offsets, noisy, dropped, late and jittered joint_states) RX200 reach
succeeds >= 0.9 over 20 episodes with the shipped sim2real config, the nominal policy beside it.

1. (``--train``) ``uniros train RX200ReacherGoalSim-v0`` (the shipped config, nominal worlds) and
   ``uniros train RX200ReacherGoalSim-v0 --config config/training/sim2real/RX200ReacherGoalSim-v0.yaml``
   (randomised worlds), one after the other, into ``--output``; or ``--nominal RUN --sim2real RUN``:
   run directories trained before;
2. for each gap profile (``none``, ``mild``, ``hard`` by default) and each run: ``uniros-fake-robot
   --arm config/arms/rx200.yaml --gap PROFILE --gap-seed SEED`` on a private Zenoh router on a free
   loopback port (never 7447; a fresh robot and router per evaluation, the same seeded gap), then
   ``uniros eval RUN --env RX200ReacherGoalReal-v0 --episodes N`` in a child process joined to that
   graph (``UNIROS_TRANSPORT=zenoh``, ``UNIROS_ZENOH_ROUTER``), at the Real env's loop rate (wall
   clock); the robot is stopped by PID; ROS domain ``$ROS_DOMAIN_ID``, never 0 (101-200 when unset);
3. the success rates side by side, per profile, with any evaluation's failure (its last error line).

The RX200 by default; ``--arm FILE`` plays another arm (a shipped one, or one added with ``uniros arm
add``: the IDs are ``<name>ReacherGoalSim-v0`` / ``<name>ReacherGoalReal-v0`` from the file's ``name``, the
sim2real config ``config/training/sim2real/<Sim ID>.yaml`` where one is shipped, else ``--sim2real-config``).

    python benchmarks/bench_sim2real_gap.py --nominal runs/A --sim2real runs/B [--profiles none mild hard]
                                            [--episodes 20] [--gap-seed 0]
    AMENT_PREFIX_PATH=ws/install UNIROS_ARMS=arms/OMX.yaml python benchmarks/bench_sim2real_gap.py \
        --arm arms/OMX.yaml --nominal runs/A --sim2real runs/B
    python benchmarks/bench_sim2real_gap.py --train [--output runs] [--sim2real-steps 30000]

An evaluation that fails (the Real env's ResetError, a stale joint state, ...) is reported in its
cell and the others still run; ``--retries N`` evaluates a failed cell again (the failures are still
listed below the table).
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ARM = ROOT / "config" / "arms" / "rx200.yaml"
SIM2REAL_CONFIGS = ROOT / "config" / "training" / "sim2real"
_RATE = re.compile(r"success rate ([0-9.]+) \[([0-9.]+), ([0-9.]+)\]")
_LENGTH = re.compile(r"mean length ([0-9.]+)")
_FINAL = re.compile(r"final evaluation .* success rate ([0-9.]+ \[[0-9.]+, [0-9.]+\])")


@dataclass
class Cell:
    """One run's evaluation on one gap profile."""

    rate: float | None
    interval: str
    seconds: float
    error: str = ""
    length: float | None = None
    tries: int = 1

    def text(self) -> str:
        again = f", try {self.tries}" if self.tries > 1 else ""
        if self.rate is None:
            return f"FAILED ({self.seconds:.0f} s{again})"
        return f"{self.rate:.2f} {self.interval} len {self.length or 0:.1f} ({self.seconds:.0f} s{again})"


def _cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "uniros.cli", *args]


def _last_error(text: str) -> str:
    """The traceback's last line that names an error (or the output's last line)."""
    lines = [line.strip() for line in text.strip().splitlines() if line.strip()]
    for line in reversed(lines):
        if re.search(r"\w*(Error|Exception|Interrupt)\b:", line) or "error:" in line:
            return line[:400]
    return lines[-1][:400] if lines else "(no output)"


def reach_ids(arm: Path) -> tuple[str, str]:
    """The arm file's goal-reach IDs: (Sim, Real)."""
    from rl_environments.arm_file import load_arm_file

    name = load_arm_file(arm).name
    return f"{name}ReacherGoalSim-v0", f"{name}ReacherGoalReal-v0"


def train(sim_id: str, output: Path, name: str, config: Path | None, steps: int | None,
          timeout: float) -> tuple[Path, float, str]:
    """``uniros train`` one run into ``output/name``: its directory, wall seconds, final evaluation."""
    args = ["train", sim_id, "--output", str(output), "--name", name, "--no-video", "--no-progress"]
    if config is not None:
        args += ["--config", str(config)]
    if steps is not None:
        args += ["--steps", str(steps)]
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    print("$ uniros " + " ".join(args), flush=True)
    t0 = time.perf_counter()
    proc = subprocess.run(_cli(*args), env=env, cwd=ROOT, capture_output=True, text=True, timeout=timeout)
    seconds = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"uniros {' '.join(args)} failed ({proc.returncode}): {_last_error(proc.stderr)}")
    final = _FINAL.search(proc.stdout)
    return output / name, seconds, final.group(1) if final else "?"


def evaluate_on_gap(run: Path, profile: str, *, real_id: str, episodes: int, gap_seed: int, arm: Path,
                    timeout: float, log: Path | None) -> Cell:
    """``uniros eval RUN --env REAL_ID`` against a fresh fake robot with ``profile``."""
    from multiros.hardware.process import FakeRobotProcess
    from multiros.ros.processes import child_environment, private_context, private_environment
    from rl_environments.arm_file import load_arm_file

    namespace = load_arm_file(arm).real.namespace
    ctx = private_context()
    t0 = time.perf_counter()
    try:
        robot = FakeRobotProcess(None, context=ctx, module="uniros.fake_robot", namespace=namespace,
                                 args=["--arm", str(arm), "--gap", profile, "--gap-seed", str(gap_seed),
                                       "--log-level", "WARNING"], timeout_sec=120.0, cwd=str(ROOT))
        try:
            env = private_environment()
            env.update(child_environment(ctx))  # UNIROS_TRANSPORT=zenoh, UNIROS_ZENOH_ROUTER, credentials
            env["MUJOCO_GL"] = os.environ.get("MUJOCO_GL", "egl")
            args = ["eval", str(run), "--env", real_id, "--episodes", str(episodes)]
            t0 = time.perf_counter()
            try:
                proc = subprocess.run(_cli(*args), env=env, cwd=ROOT, capture_output=True, text=True,
                                      timeout=timeout)
            except subprocess.TimeoutExpired as exc:
                out = (exc.stdout or b"").decode() if isinstance(exc.stdout, bytes) else (exc.stdout or "")
                err = (exc.stderr or b"").decode() if isinstance(exc.stderr, bytes) else (exc.stderr or "")
                if log is not None:
                    log.write_text(out + "\n--- stderr ---\n" + err)
                return Cell(None, "", time.perf_counter() - t0, f"timed out after {timeout:.0f} s")
            seconds = time.perf_counter() - t0
            if log is not None:
                log.write_text(proc.stdout + "\n--- stderr ---\n" + proc.stderr)
            found = _RATE.findall(proc.stdout)
            if proc.returncode != 0 or not found:
                return Cell(None, "", seconds, f"rc {proc.returncode}: {_last_error(proc.stderr or proc.stdout)}")
            rate, low, high = found[-1]
            length = _LENGTH.findall(proc.stdout)
            return Cell(float(rate), f"[{low}, {high}]", seconds, length=float(length[-1]) if length else None)
        finally:
            robot.stop()
    except Exception as exc:  # the robot did not start: that cell, not the whole table
        return Cell(None, "", time.perf_counter() - t0, f"{type(exc).__name__}: {exc}"[:400])
    finally:
        ctx.try_shutdown()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--nominal", type=Path, help="run directory of the nominal policy (shipped config)")
    parser.add_argument("--sim2real", type=Path, help="run directory of the randomised policy (sim2real config)")
    parser.add_argument("--train", action="store_true", help="train both runs first (into --output)")
    parser.add_argument("--output", type=Path, default=ROOT / "runs", help="parent of the trained runs (runs)")
    parser.add_argument("--nominal-steps", type=int, help="override the nominal config's training_steps")
    parser.add_argument("--sim2real-steps", type=int, help="override the sim2real config's training_steps")
    parser.add_argument("--profiles", nargs="+", default=["none", "mild", "hard"], help="gap profiles")
    parser.add_argument("--episodes", type=int, default=20, help="evaluation episodes per run and profile")
    parser.add_argument("--gap-seed", type=int, default=0, help="the fake robot's --gap-seed")
    parser.add_argument("--arm", type=Path, default=ARM, help="the arm file the fake robot plays (rx200.yaml)")
    parser.add_argument("--sim2real-config", type=Path,
                        help="the randomised run's config (--train; default: the one shipped for the arm's ID)")
    parser.add_argument("--eval-timeout", type=float, default=1800.0, help="seconds one evaluation may take")
    parser.add_argument("--retries", type=int, default=0,
                        help="evaluate a failed cell again up to this many times (each failure is still reported)")
    parser.add_argument("--logs", type=Path, help="write each evaluation's output into this folder")
    args = parser.parse_args()
    # Never domain 0 (a user's robots): the private graphs' ROS domain, handed to every child.
    if os.environ.get("ROS_DOMAIN_ID", "0") == "0":
        os.environ["ROS_DOMAIN_ID"] = str(101 + os.getpid() % 100)

    sim_id, real_id = reach_ids(args.arm)
    runs: dict[str, Path] = {}
    if args.train:
        sim2real_config = args.sim2real_config or SIM2REAL_CONFIGS / f"{sim_id}.yaml"
        if not sim2real_config.is_file():
            parser.error(f"no sim2real config shipped for {sim_id}: give --sim2real-config FILE")
        stamp = time.strftime("%Y%m%d_%H%M%S")
        for label, config, steps in (("nominal", None, args.nominal_steps),
                                     ("sim2real", sim2real_config, args.sim2real_steps)):
            run, secs, final = train(sim_id, args.output, f"gap_{label}_{stamp}", config, steps, timeout=6 * 3600)
            print(f"{label}: {run} trained in {secs:.0f} s, final evaluation (simulation) {final}", flush=True)
            runs[label] = run
    else:
        if args.nominal is None and args.sim2real is None:
            parser.error("give --nominal RUN and/or --sim2real RUN, or --train")
        runs = {k: v for k, v in (("nominal", args.nominal), ("sim2real", args.sim2real)) if v is not None}
    for label, run in runs.items():
        if not (run / "run.json").is_file():
            parser.error(f"--{label} {run}: not a run directory (no run.json)")
    if args.logs is not None:
        args.logs.mkdir(parents=True, exist_ok=True)

    table: dict[tuple[str, str], Cell] = {}
    for profile in args.profiles:
        for label, run in runs.items():
            print(f"$ uniros-fake-robot --arm {args.arm} --gap {profile} --gap-seed {args.gap_seed} &  "
                  f"uniros eval {run} --env {real_id} --episodes {args.episodes}", flush=True)
            errors: list[str] = []
            for attempt in range(1, args.retries + 2):
                log = None if args.logs is None else args.logs / f"{label}_{Path(profile).stem}_{attempt}.log"
                cell = evaluate_on_gap(run, profile, real_id=real_id, episodes=args.episodes, gap_seed=args.gap_seed,
                                       arm=args.arm, timeout=args.eval_timeout, log=log)
                cell.tries = attempt
                if cell.error:
                    errors.append(f"try {attempt}: {cell.error}")
                if cell.rate is not None:
                    break
                print(f"  {label} on --gap {profile} failed, {cell.error}", flush=True)
            cell.error = "; ".join(errors)
            table[profile, label] = cell
            load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
            print(f"  {label} on --gap {profile}: {cell.text()}, load average after {load}"
                  + (f"  {cell.error}" if cell.error else ""), flush=True)

    labels = list(runs)
    print(f"\n{real_id} on uniros-fake-robot --arm {args.arm.name} --gap PROFILE --gap-seed {args.gap_seed}: "
          f"success over {args.episodes} episodes [95% CI], mean episode length in steps (evaluation wall seconds)")
    print(f"{'gap':<8}" + "".join(f"{label + ' (' + runs[label].name + ')':<48}" for label in labels))
    for profile in args.profiles:
        print(f"{profile:<8}" + "".join(f"{table[profile, label].text():<48}" for label in labels))
    failures = [(p, label, c.error) for (p, label), c in table.items() if c.error]
    for profile, label, error in failures:
        print(f"  {label} on --gap {profile} failed: {error}")


if __name__ == "__main__":
    main()
