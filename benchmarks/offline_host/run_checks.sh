#!/usr/bin/env bash
# The measurements issues 36 and 37 need a 16-core GPU host for, each as one prepared command (the
# team's device machine: no network, Python 3.12 with torch; wheels from fetch_wheels.sh in .whl):
#
#     bash benchmarks/offline_host/run_checks.sh {scaling|pixels} [OUTDIR] [PIXEL_SECONDS]
#
# On the device machine, the wheels carried (a call may run 10 minutes: one check a call):
#     run(command="bash benchmarks/offline_host/run_checks.sh scaling", carry=[".whl"], timeout_s=600)
#
# Both install the wheels into /tmp/site (skipped when uniros already imports) and run `uniros doctor`
# (GL backend, GPU, torch device). Then:
# * scaling: benchmarks/bench_scaling.py on all cores (one env; make_vec(N) for N = 1, 8, 32, 128 with
#   each share's busy fraction and run-queue wait; process mode; pin_workers; the physics limit;
#   FetchReach-v4 and its AsyncVectorEnv), with the plot; about 4 minutes on 16 cores, cut at 500 s;
# * pixels: the RX200's shipped pixel config, `--device auto`, for PIXEL_SECONDS (default 480) of wall
#   clock; its evaluations.csv says when it reached 0.9.
# BENCH_ARGS replaces the benchmark's arguments (default: --rounds 2); PYTHON the interpreter.
# Logs, the plot and the csv land in OUTDIR (default $OUT, else ./offline_host_out); the pixel run's
# checkpoints in /tmp/offline_host_runs (large: its replay buffer holds images).
set -uo pipefail
cd "$(dirname "$0")/../.."
what=${1:-}
out=${2:-${OUT:-offline_host_out}}
pixel_seconds=${3:-480}
case $what in scaling|pixels) ;; *) echo "usage: $0 {scaling|pixels} [OUTDIR] [PIXEL_SECONDS]" >&2; exit 2;; esac
mkdir -p "$out"
export PYTHONUNBUFFERED=1 MUJOCO_GL=${MUJOCO_GL:-egl}
py=${PYTHON:-python3}
if ! "$py" -c "import uniros" 2>/dev/null; then
    "$py" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl \
        || { echo "installing the wheels in .whl failed" >&2; exit 1; }
    export PYTHONPATH=/tmp/site${PYTHONPATH:+:$PYTHONPATH}
fi
nproc > "$out/cores.txt"
"$py" -m uniros.cli doctor 2>&1 | tee "$out/doctor.txt"
if [ "$what" = scaling ]; then
    # shellcheck disable=SC2086
    timeout 500 "$py" benchmarks/bench_scaling.py ${BENCH_ARGS:---rounds 2} --plot "$out/vec_scaling.png" 2>&1 \
        | tee "$out/bench_scaling.txt"
else
    rm -rf /tmp/offline_host_runs
    timeout -s INT -k 60 "$pixel_seconds" "$py" -m uniros.cli train RX200ReacherGoalSim-v0 \
        --config config/training/pixels/RX200ReacherGoalSim-v0.yaml --device auto --no-video --no-progress \
        --eval-episodes 20 --output /tmp/offline_host_runs --name rx200_pixels 2>&1 | tee "$out/pixels.txt"
    cp /tmp/offline_host_runs/rx200_pixels/evaluations.csv "$out/pixels_evaluations.csv"
fi
