"""The OpenGL backend chosen before MuJoCo is imported (multiros.gl_backend): EGL on an NVIDIA GPU
when its EGL vendor is installed, software otherwise, the user's MUJOCO_GL always. Vendor files
and GPUs are mocked (folders of glvnd JSON files), so this runs on any machine."""

from __future__ import annotations

import json
import logging
import os
import subprocess
import sys
from pathlib import Path

import pytest

from multiros import gl_backend
from multiros.gl_backend import choose, egl_vendors

HEADLESS: dict[str, str] = {}


def _vendor(folder: Path, name: str, library: str) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / name).write_text(json.dumps({"file_format_version": "1.0.0", "ICD": {"library_path": library}}))


def test_vendor_files_are_read_as_glvnd_reads_them(tmp_path):
    share, etc = tmp_path / "share", tmp_path / "etc"
    _vendor(share, "10_nvidia.json", "libEGL_nvidia.so.0")
    _vendor(share, "50_mesa.json", "libEGL_mesa.so.0")
    (share / "broken.json").write_text("{not json")
    (share / "README").write_text("not a vendor file")
    assert egl_vendors({}, [str(etc), str(share)]) == ["libEGL_nvidia.so.0", "libEGL_mesa.so.0"]
    _vendor(etc, "only.json", "libEGL_other.so")
    assert egl_vendors({"__EGL_VENDOR_LIBRARY_DIRS": str(etc)}, [str(share)]) == ["libEGL_other.so"]
    assert egl_vendors({"__EGL_VENDOR_LIBRARY_FILENAMES": str(share / "50_mesa.json")}) == ["libEGL_mesa.so.0"]


def test_nvidia_egl_means_the_gpu_else_software():
    gpu = choose(HEADLESS, platform="linux", vendors=["libEGL_mesa.so.0", "libEGL_nvidia.so.0"], gpu=True)
    assert (gpu.backend, gpu.kind) == ("egl", "gpu") and "libEGL_nvidia.so.0" in gpu.reason and not gpu.gpu_unused
    mesa = choose(HEADLESS, platform="linux", vendors=["libEGL_mesa.so.0"], osmesa=True)
    assert (mesa.backend, mesa.kind) == ("egl", "software") and "no NVIDIA EGL vendor" in mesa.reason
    osmesa = choose(HEADLESS, platform="linux", vendors=[], osmesa=True)
    assert (osmesa.backend, osmesa.kind) == ("osmesa", "software")
    nothing = choose(HEADLESS, platform="linux")
    assert nothing.backend == "egl" and "libosmesa6" in nothing.reason
    unused = choose(HEADLESS, platform="linux", vendors=["libEGL_mesa.so.0"], gpu=True)
    assert unused.kind == "software" and "NVIDIA_DRIVER_CAPABILITIES" in unused.reason


def test_a_vendor_file_without_libegl_is_no_egl():
    """A container given the NVIDIA driver's files but not glvnd's libEGL.so.1: MUJOCO_GL=egl would make
    ``import mujoco`` fail (seen on a GPU machine), so OSMesa when found, else MuJoCo's default."""
    nvidia = ["libEGL_nvidia.so.0"]
    osmesa = choose(HEADLESS, platform="linux", vendors=nvidia, gpu=True, egl=False, osmesa=True)
    assert (osmesa.backend, osmesa.kind) == ("osmesa", "software") and "install libegl1" in osmesa.reason
    assert osmesa.gpu_unused  # logged as a warning
    bare = choose(HEADLESS, platform="linux", vendors=nvidia, gpu=True, egl=False)
    assert (bare.backend, bare.kind) == (None, "none") and "libegl1" in bare.reason and "libosmesa6" in bare.reason
    mesa = choose(HEADLESS, platform="linux", vendors=["libEGL_mesa.so.0"], egl=False)
    assert mesa.backend is None and "no NVIDIA EGL vendor found and no OSMesa" in mesa.reason


def test_apply_leaves_mujoco_gl_unset_without_any_gl_library(monkeypatch, caplog):
    monkeypatch.setattr(gl_backend, "egl_vendors", lambda env=None, dirs=None: ["libEGL_nvidia.so.0"])
    monkeypatch.setattr(gl_backend, "_egl_found", lambda: False)
    monkeypatch.setattr(gl_backend, "_osmesa_found", lambda: False)
    monkeypatch.delitem(sys.modules, "mujoco", raising=False)
    monkeypatch.setattr(sys, "platform", "linux")
    env: dict[str, str] = {}
    assert gl_backend.apply(env).kind == "none" and env == {}
    monkeypatch.setattr(gl_backend, "_CHOICE", [gl_backend.apply({})])
    monkeypatch.setattr(gl_backend, "_LOGGED", [])
    with caplog.at_level(logging.INFO, logger="test.gl"):
        gl_backend.log_choice_once(logging.getLogger("test.gl"))
    assert caplog.records[-1].levelno == logging.WARNING and "libegl1" in caplog.records[-1].getMessage()


def test_a_fresh_process_without_libegl_still_imports_mujoco(tmp_path):
    """The GPU machine's case end to end: an NVIDIA vendor file, and no libEGL.so.1 or libOSMesa on the
    library search path (ctypes' lookup answers None for them): MUJOCO_GL is left to MuJoCo, whose
    import then works."""
    _vendor(tmp_path, "10_nvidia.json", "libEGL_nvidia.so.0")
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "DISPLAY", "WAYLAND_DISPLAY")}
    env["__EGL_VENDOR_LIBRARY_DIRS"] = str(tmp_path)
    probe = ("import ctypes.util, os; found = ctypes.util.find_library; "
             "ctypes.util.find_library = lambda n: None if n in ('EGL', 'OSMesa') else found(n); "
             "import multiros, mujoco; from multiros import gl_backend; "
             "print(os.environ.get('MUJOCO_GL', '-'), gl_backend.current().kind)")
    out = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=120,
                         stdin=subprocess.DEVNULL)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["-", "none"]


def test_the_user_and_a_display_decide_first():
    assert choose({"MUJOCO_GL": "osmesa"}, platform="linux", vendors=["libEGL_nvidia.so.0"]).backend == "osmesa"
    shown = choose({"DISPLAY": ":0"}, platform="linux", vendors=["libEGL_nvidia.so.0"])
    assert shown.backend is None and shown.kind == "display"
    assert choose(HEADLESS, platform="darwin").backend is None


def test_apply_sets_mujoco_gl_only_when_unset(monkeypatch):
    env = {"MUJOCO_GL": "glfw"}
    assert gl_backend.apply(env).kind == "user" and env == {"MUJOCO_GL": "glfw"}
    monkeypatch.setattr(gl_backend, "egl_vendors", lambda env=None, dirs=None: ["libEGL_nvidia.so.0"])
    monkeypatch.delitem(sys.modules, "mujoco", raising=False)  # as before MuJoCo's first import
    monkeypatch.setattr(sys, "platform", "linux")
    env = {}
    assert gl_backend.apply(env).kind == "gpu" and env == {"MUJOCO_GL": "egl"}
    monkeypatch.setattr(gl_backend, "egl_vendors", lambda env=None, dirs=None: [])
    monkeypatch.setattr(gl_backend, "_osmesa_found", lambda: True)
    env = {}
    assert gl_backend.apply(env).kind == "software" and env == {"MUJOCO_GL": "osmesa"}
    monkeypatch.setitem(sys.modules, "mujoco", object())  # MuJoCo already imported: its choice is made
    env = {}
    assert gl_backend.apply(env).backend == "osmesa" and env == {}


def test_a_fresh_process_picks_egl_from_a_mocked_nvidia_vendor_and_says_so_once(tmp_path):
    """``import multiros`` sets MUJOCO_GL before MuJoCo is imported; the first renderer logs the choice once."""
    _vendor(tmp_path, "10_nvidia.json", "libEGL_nvidia.so.0")
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "DISPLAY", "WAYLAND_DISPLAY")}
    env["__EGL_VENDOR_LIBRARY_DIRS"] = str(tmp_path)
    probe = ("import os, multiros, mujoco; from multiros import gl_backend; "
             "print(os.environ['MUJOCO_GL'], gl_backend.current().kind)")
    out = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=120,
                         stdin=subprocess.DEVNULL)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["egl", "gpu"]


def test_the_choice_is_logged_once(monkeypatch, caplog):
    monkeypatch.setattr(gl_backend, "_CHOICE", [choose(HEADLESS, platform="linux", vendors=["libEGL_mesa.so.0"])])
    monkeypatch.setattr(gl_backend, "_LOGGED", [])
    logger = logging.getLogger("test.gl")
    with caplog.at_level(logging.INFO, logger="test.gl"):
        gl_backend.log_choice_once(logger)
        gl_backend.log_choice_once(logger)
    lines = [r for r in caplog.records if r.name == "test.gl"]
    assert len(lines) == 1 and lines[0].levelno == logging.INFO
    assert "MUJOCO_GL=egl: no NVIDIA EGL vendor found: rendering in software" in lines[0].getMessage()
    monkeypatch.setattr(gl_backend, "_CHOICE", [choose(HEADLESS, platform="linux", vendors=["libEGL_mesa.so.0"],
                                                       gpu=True)])
    monkeypatch.setattr(gl_backend, "_LOGGED", [])
    with caplog.at_level(logging.INFO, logger="test.gl"):
        gl_backend.log_choice_once(logger)
    assert caplog.records[-1].levelno == logging.WARNING  # a GPU left unused is worth a warning


@pytest.mark.parametrize("kind", ["user", "display"])
def test_nothing_is_logged_for_a_choice_the_user_made(monkeypatch, caplog, kind):
    monkeypatch.setattr(gl_backend, "_CHOICE", [gl_backend.GLChoice("egl" if kind == "user" else None, kind, "x")])
    monkeypatch.setattr(gl_backend, "_LOGGED", [])
    with caplog.at_level(logging.DEBUG):
        gl_backend.log_choice_once(logging.getLogger("test.gl"))
    assert not [r for r in caplog.records if r.name == "test.gl"]
