"""``uniros doctor``: what this machine offers uniros, found the way uniros finds it.

One line per finding: the OpenGL backend MuJoCo renders with (and whether a frame renders, in a
child process so that a broken driver cannot take this one down), the GPU and EGL vendors, torch
and the device ``--device auto`` picks, rclpy and its distribution, the ROS middleware, MuJoCo. It
only reports: it changes nothing and exits 0, so it can be pasted into an issue as it is.
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import json
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

__all__ = ["GL_PROBE", "findings", "main"]

#: Renders one small frame with MuJoCo and prints ``{"ok": ..., "renderer": ..., "error": ...}``.
GL_PROBE = r"""
import json, multiros, mujoco
out = {"backend": __import__("os").environ.get("MUJOCO_GL")}
try:
    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><geom size='.1'/></worldbody></mujoco>")
    renderer = mujoco.Renderer(model, 16, 16)
    renderer.update_scene(mujoco.MjData(model))
    renderer.render()
    try:
        from OpenGL import GL
        name = GL.glGetString(GL.GL_RENDERER)
        out["renderer"] = name.decode() if isinstance(name, bytes) else str(name)
    except Exception as exc:
        out["renderer"] = f"(unknown: {type(exc).__name__})"
    renderer.close()
    out["ok"] = True
except Exception as exc:
    out["ok"], out["error"] = False, f"{type(exc).__name__}: {exc}"[:300]
print(json.dumps(out))
"""


def _gl(timeout: float) -> list[tuple[str, str]]:
    from multiros import gl_backend

    choice = gl_backend.current() or gl_backend.apply({**os.environ})
    backend = os.environ.get("MUJOCO_GL") or "(MuJoCo's default)"
    rows = [("GL backend", f"MUJOCO_GL={backend}: {choice.reason}"),
            ("EGL vendors", ", ".join(gl_backend.egl_vendors()) or "none found (glvnd's egl_vendor.d)")]
    try:
        proc = subprocess.run([sys.executable, "-c", GL_PROBE], capture_output=True, text=True, timeout=timeout,
                              stdin=subprocess.DEVNULL, env=dict(os.environ))
        result = json.loads(proc.stdout.strip().splitlines()[-1]) if proc.stdout.strip() else {}
        if not result:
            tail = (proc.stderr.strip().splitlines() or ["no output"])[-1]
            result = {"ok": False, "error": f"the probe exited with code {proc.returncode}: {tail[:300]}"}
    except subprocess.TimeoutExpired:
        result = {"ok": False, "error": f"no frame within {timeout:g} s"}
    except (OSError, ValueError) as exc:
        result = {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
    if result.get("ok"):
        rows.append(("GL works", f"yes: a frame rendered (renderer {result.get('renderer', '?')})"))
    else:
        rows.append(("GL works", f"no: {result.get('error')} (camera envs and videos will fail; "
                                 "docs/pitfalls.md, headless rendering)"))
    return rows


def _gpu() -> list[tuple[str, str]]:
    from multiros.gl_backend import nvidia_gpu_present

    rows = [("NVIDIA device", "/dev/nvidiactl present" if nvidia_gpu_present() else "none (/dev/nvidiactl absent)")]
    try:
        import torch
    except ImportError as exc:
        return [*rows, ("torch", f"not importable ({exc})")]
    rows.append(("torch", f"{torch.__version__} (CUDA build {torch.version.cuda or 'none: CPU only'})"))
    if torch.cuda.is_available():
        names = [torch.cuda.get_device_name(i) for i in range(torch.cuda.device_count())]
        rows.append(("CUDA", f"available: {', '.join(f'cuda:{i} {n}' for i, n in enumerate(names))}"))
        rows.append(("--device auto", "cuda for policies that see camera images, cpu for MLPs"))
    else:
        rows.append(("CUDA", "not available"))
        rows.append(("--device auto", "cpu (no CUDA GPU)"))
    return rows


def _rclpy_distro() -> str:
    """The ROS 2 distribution of the rclpy that would be imported, from its path or its wheel."""
    spec = importlib.util.find_spec("rclpy")
    origin = str(getattr(spec, "origin", "") or "")
    parts = origin.split(os.sep)
    if "ros" in parts and parts.index("ros") + 1 < len(parts):
        return parts[parts.index("ros") + 1]
    for dist in importlib.metadata.packages_distributions().get("rclpy", []):
        if dist.startswith("ros-") and dist.endswith("-rclpy"):
            return dist.split("-")[1]
    return "unknown"


def _ros() -> list[tuple[str, str]]:
    from multiros.ros.interfaces import SUPPORTED_DISTROS
    from multiros.ros.transport.rclpy.loader import RMW_ENV, rclpy_available

    rows = []
    distro = os.environ.get("ROS_DISTRO", "").strip()
    if not distro:
        rows.append(("ROS_DISTRO", "unset (uniros speaks Jazzy's interfaces)"))
    elif distro.lower() in SUPPORTED_DISTROS:
        rows.append(("ROS_DISTRO", f"{distro} (supported)"))
    else:
        rows.append(("ROS_DISTRO", f"{distro}: not supported for the zenoh and rclpy transports (supported: "
                                   f"{', '.join(SUPPORTED_DISTROS)}); simulated envs on the default inproc "
                                   "transport work"))
    if rclpy_available():
        spec = importlib.util.find_spec("rclpy")
        rows.append(("rclpy", f"importable ({_rclpy_distro()}; {getattr(spec, 'origin', '?')})"))
    else:
        rows.append(("rclpy", "not importable (--transport rclpy needs a sourced ROS 2 or the PyPI wheels: "
                              "docs/ros2_system.md)"))
    rmw = os.environ.get(RMW_ENV, "").strip()
    rows.append(("RMW", f"{rmw} ({RMW_ENV})" if rmw else f"rclpy's default ({RMW_ENV} unset; rmw_fastrtps_cpp on a "
                                                          "stock install)"))
    rows.append(("uniros transport", f"{os.environ.get('UNIROS_TRANSPORT') or 'inproc'} for training "
                                     "(UNIROS_TRANSPORT or --transport)"))
    return rows


def _versions() -> list[tuple[str, str]]:
    rows = []
    for module, dist in (("mujoco", "mujoco"), ("stable_baselines3", "stable-baselines3"), ("gymnasium", "gymnasium")):
        try:
            rows.append((module, importlib.metadata.version(dist)))
        except importlib.metadata.PackageNotFoundError:
            rows.append((module, "not installed"))
    rows.append(("python", sys.version.split()[0]))
    return rows


def _arms() -> list[tuple[str, str]]:
    """The arm files of ``UNIROS_ARMS`` (and ``UNIROS_ARMS_JSON``, paths that hold ``:``): registered, or why not."""
    from rl_environments.arm_registry import env_arm_errors, env_arm_paths, registered_arms

    entries = env_arm_paths()
    held = {spec.path for spec in registered_arms().values()}
    registered = sum(1 for entry in entries if Path(entry).expanduser().resolve() in held)
    rows = [("UNIROS_ARMS", f"{registered} of {len(entries)} arm file(s) registered; "
                            f"arms: {', '.join(sorted(registered_arms()))}")]
    rows += [("UNIROS_ARMS error", why) for why in env_arm_errors()]
    return rows


def findings(gl_timeout: float = 60.0) -> list[tuple[str, str]]:
    """Every finding as ``(what, found)``; a part that fails says so in its row."""
    rows: list[tuple[str, str]] = []
    parts: list[tuple[str, Callable[[], list[tuple[str, str]]]]] = [
        ("GL", lambda: _gl(gl_timeout)), ("GPU", _gpu), ("ROS", _ros), ("arms", _arms), ("versions", _versions)]
    for name, part in parts:
        try:
            rows += part()
        except Exception as exc:  # noqa: BLE001 - a report: one broken part must not hide the rest
            rows.append((name, f"could not check: {type(exc).__name__}: {exc}"))
    return rows


def main(args: Any = None) -> int:
    """Print the findings, one a line; exit code 0."""
    for what, found in findings():
        print(f"{what:18s} {found}")
    return 0
