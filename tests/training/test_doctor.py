"""``uniros doctor`` reports what it finds and always exits 0 (GPU and GL failures mocked)."""

from __future__ import annotations

import pytest

import uniros.doctor as doctor
from uniros.cli import main as cli_main


def _rows(capsys) -> dict[str, str]:
    assert cli_main(["doctor"]) == 0
    out = capsys.readouterr().out
    return {line[:18].strip(): line[18:].strip() for line in out.splitlines() if line.strip()}


def test_doctor_reports_every_part(capsys):
    rows = _rows(capsys)
    for key in ("GL backend", "EGL vendors", "GL works", "torch", "CUDA", "--device auto", "ROS_DISTRO", "rclpy",
                "RMW", "mujoco", "stable_baselines3"):
        assert key in rows, rows
    assert rows["GL backend"].startswith("MUJOCO_GL=")
    assert rows["GL works"].startswith(("yes: a frame rendered", "no: "))
    import mujoco
    import torch

    assert rows["mujoco"] == mujoco.__version__ and rows["torch"].startswith(torch.__version__)


def test_doctor_says_what_fails_and_still_exits_0(monkeypatch, capsys):
    import torch

    monkeypatch.setattr(doctor, "GL_PROBE", "import sys; sys.stderr.write('EGL: no display\\n'); sys.exit(3)")
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 1)
    monkeypatch.setattr(torch.cuda, "get_device_name", lambda i: "NVIDIA H200")
    monkeypatch.setenv("ROS_DISTRO", "humble")
    monkeypatch.setenv("RMW_IMPLEMENTATION", "rmw_cyclonedds_cpp")
    rows = _rows(capsys)
    assert rows["GL works"] == ("no: the probe exited with code 3: EGL: no display (camera envs and videos will "
                                "fail; docs/pitfalls.md, headless rendering)")
    assert rows["CUDA"] == "available: cuda:0 NVIDIA H200"
    assert rows["--device auto"] == "cuda for policies that see camera images, cpu for MLPs"
    assert rows["ROS_DISTRO"].startswith("humble: not supported for the zenoh and rclpy transports")
    assert rows["RMW"] == "rmw_cyclonedds_cpp (RMW_IMPLEMENTATION)"


def test_a_part_that_raises_is_a_row(monkeypatch, capsys):
    def broken() -> list:
        raise RuntimeError("driver gone")

    monkeypatch.setattr(doctor, "_gpu", broken)
    monkeypatch.setattr(doctor, "GL_PROBE", "print('{\"ok\": true, \"renderer\": \"mock\"}')")
    rows = _rows(capsys)
    assert rows["GPU"] == "could not check: RuntimeError: driver gone"
    assert rows["GL works"] == "yes: a frame rendered (renderer mock)"


@pytest.mark.parametrize("timeout", [0.001])
def test_a_hanging_probe_is_bounded(monkeypatch, timeout):
    monkeypatch.setattr(doctor, "GL_PROBE", "import time; time.sleep(30)")
    rows = dict(doctor._gl(timeout))
    assert rows["GL works"].startswith(f"no: no frame within {timeout:g} s")


def test_a_reader_that_goes_away_is_no_traceback():
    """`uniros doctor | head -1`: the pipe closes after one line; no BrokenPipeError traceback."""
    import os
    import subprocess
    import sys

    code = ("import sys; from uniros.cli import main; import uniros.doctor as d; "
            "d.findings = lambda gl_timeout=60.0: [(f'row {i}', 'x' * 200) for i in range(5000)]; "
            "sys.exit(main(['doctor']))")
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            stdin=subprocess.DEVNULL, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    assert proc.stdout is not None and proc.stdout.readline().startswith(b"row 0")
    proc.stdout.close()
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 1 and b"Traceback" not in err and b"BrokenPipe" not in err, err


def test_arm_files_of_both_variables_are_counted(monkeypatch):
    """Paths that hold ':' reach child processes through UNIROS_ARMS_JSON: the doctor counts them too."""
    import json

    monkeypatch.setenv("UNIROS_ARMS", "/nowhere/a.yaml")
    monkeypatch.setenv("UNIROS_ARMS_JSON", json.dumps(["/runs:2026/b.yaml"]))
    (label, text), *_ = doctor._arms()
    assert label == "UNIROS_ARMS" and "0 of 2 arm file(s) registered" in text  # both counted, neither there
