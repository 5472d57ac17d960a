#!/usr/bin/env bash
# Wheels for a host with no network and its own Python (3.12, x86-64) that already holds torch,
# numpy, pyyaml, tensorboard, matplotlib, imageio, rich, tqdm, lxml and scipy (the team's GPU
# machine; see run_checks.sh beside this file). Run here, where PyPI is reachable:
#
#     bash benchmarks/offline_host/fetch_wheels.sh [DIR]      # DIR defaults to .whl
#
# It takes the versions this checkout's .venv holds (so both hosts run the same libraries), the
# project itself as a wheel, and prints the total size: a device call carries 64 MiB at most, the
# working tree (about 9 MiB) included. mujoco-studio (13 MiB), which `mujoco` names as a requirement
# but `import mujoco` does not load, is left out: these are installed with --no-deps.
set -euo pipefail
cd "$(dirname "$0")/../.."
dir=${1:-.whl}
py=${PYTHON:-.venv/bin/python}
mkdir -p "$dir"
names="mujoco mujoco-core glfw PyOpenGL gymnasium gymnasium-robotics Farama-Notifications
cloudpickle PettingZoo eclipse-zenoh xacro yourdfpy trimesh pycollada stable_baselines3 sb3_contrib"
pins=$("$py" - $names <<'PY'
import sys
from importlib.metadata import version
print(" ".join(f"{n}=={version(n)}" for n in sys.argv[1:]))
PY
)
platforms=""
# oldest first: pip prefers the first tag that matches, and the host may have an older glibc than this one
for p in manylinux1 manylinux2014 manylinux_2_17 manylinux_2_24 manylinux_2_27 manylinux_2_28 manylinux_2_31 \
         manylinux_2_34 manylinux_2_35 manylinux_2_39; do
    platforms="$platforms --platform ${p}_x86_64"
done
for pin in $pins; do
    "$py" -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
        $platforms -d "$dir" "$pin"
done
rm -rf build/lib
"$py" -m pip wheel -q --no-deps --no-build-isolation -w "$dir" .
du -ch "$dir"/*.whl | tail -1
