"""Which OpenGL backend MuJoCo renders with, chosen before MuJoCo is first imported.

MuJoCo reads ``MUJOCO_GL`` once, when ``mujoco`` is imported, so ``import multiros`` (which
``uniros`` does first) calls :func:`apply` and never overrides a user's choice. Without one, on a
Linux machine without a display:

* an **NVIDIA EGL vendor** (glvnd's ``egl_vendor.d/10_nvidia.json``, what the NVIDIA driver and
  the NVIDIA container toolkit's ``graphics`` capability install) means ``egl`` on the GPU: camera
  envs and videos render at about 0.6 ms an 84 x 84 frame (H200) instead of tens of ms;
* otherwise rendering is software, said in one log line at the first rendered image: ``egl`` when
  another EGL vendor is installed (Mesa's llvmpipe, the fastest software path), else ``osmesa``
  when libOSMesa is found, else ``egl`` (whose error then names what to install);
* a vendor file without glvnd's ``libEGL.so.1`` (a container given the NVIDIA driver's files but not
  the ``libegl1`` package) is no EGL: with ``MUJOCO_GL=egl`` there, ``import mujoco`` itself fails
  (PyOpenGL finds no EGL), so ``osmesa`` is chosen when found, else MuJoCo's own default, which
  imports everywhere and renders nothing without a display; the log line names the package.

With a display, MuJoCo's own default (GLFW) is left alone: the viewer needs it.
"""

from __future__ import annotations

import json
import logging
import os
import sys
from collections.abc import Iterable, Mapping, MutableMapping
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["EGL_VENDOR_DIRS", "GLChoice", "apply", "choose", "current", "egl_vendors", "log_choice_once",
           "nvidia_gpu_present"]

#: Where glvnd looks for EGL vendor files when ``__EGL_VENDOR_LIBRARY_DIRS`` is unset.
EGL_VENDOR_DIRS: tuple[str, ...] = ("/etc/glvnd/egl_vendor.d", "/usr/share/glvnd/egl_vendor.d",
                                    "/usr/local/share/glvnd/egl_vendor.d")


@dataclass(frozen=True)
class GLChoice:
    """What :func:`choose` decided.

    Attributes:
        backend: the ``MUJOCO_GL`` value (``None``: left to MuJoCo, a display's GLFW).
        kind: ``user`` (``MUJOCO_GL`` was set), ``display``, ``gpu`` (NVIDIA EGL), ``software`` or
            ``none`` (no GL library found: camera rendering fails until one is installed).
        reason: one line saying why.
        vendors: the EGL vendor libraries found (``library_path`` of each vendor file).
        gpu_unused: an NVIDIA GPU or its EGL vendor is there, yet rendering is not on it.
    """

    backend: str | None
    kind: str
    reason: str
    vendors: tuple[str, ...] = field(default=())
    gpu_unused: bool = False


def egl_vendors(env: Mapping[str, str] | None = None, dirs: Iterable[str] | None = None) -> list[str]:
    """The EGL vendor libraries glvnd would load (``__EGL_VENDOR_LIBRARY_FILENAMES`` or the ``.json``
    files of ``__EGL_VENDOR_LIBRARY_DIRS``, else of :data:`EGL_VENDOR_DIRS`), by ``library_path``."""
    env = os.environ if env is None else env
    files: list[Path] = []
    named = env.get("__EGL_VENDOR_LIBRARY_FILENAMES", "").strip()
    if named:
        files = [Path(p) for p in named.split(":") if p]
    else:
        chosen = env.get("__EGL_VENDOR_LIBRARY_DIRS", "").strip()
        for folder in (chosen.split(":") if chosen else (dirs if dirs is not None else EGL_VENDOR_DIRS)):
            try:
                files += sorted(Path(folder).glob("*.json"))
            except OSError:
                continue
    out = []
    for path in files:
        try:
            library = json.loads(path.read_text())["ICD"]["library_path"]
        except (OSError, ValueError, KeyError, TypeError):
            continue
        if isinstance(library, str) and library:
            out.append(library)
    return out


def nvidia_gpu_present(dev: str = "/dev") -> bool:
    """Whether an NVIDIA GPU's device files exist (``/dev/nvidiactl``): a GPU rendering could use."""
    return Path(dev, "nvidiactl").exists() or Path(dev, "nvidia0").exists()


def choose(env: Mapping[str, str], *, platform: str = sys.platform, vendors: Iterable[str] = (),
           osmesa: bool = False, gpu: bool = False, egl: bool = True) -> GLChoice:
    """The backend for ``env`` (see the module docstring); ``vendors``: :func:`egl_vendors`,
    ``osmesa``: libOSMesa found, ``gpu``: :func:`nvidia_gpu_present`, ``egl``: glvnd's libEGL found."""
    found = tuple(vendors)
    user = env.get("MUJOCO_GL", "").strip()
    if user:
        return GLChoice(user, "user", f"MUJOCO_GL={user} set by the user", found)
    if not platform.startswith("linux"):
        return GLChoice(None, "display", f"MuJoCo's default for {platform}", found)
    if env.get("DISPLAY") or env.get("WAYLAND_DISPLAY"):
        return GLChoice(None, "display", "a display is set: MuJoCo's default (GLFW)", found)
    nvidia = [v for v in found if "nvidia" in v.lower()]
    if nvidia and egl:
        return GLChoice("egl", "gpu", f"NVIDIA EGL vendor ({nvidia[0]}): rendering on the GPU", found)
    if nvidia:
        why = f"an NVIDIA EGL vendor ({nvidia[0]}) but no libEGL.so.1 (install libegl1)"
    elif gpu:
        why = ("an NVIDIA GPU is present but no NVIDIA EGL vendor is installed (glvnd's egl_vendor.d has no "
               "10_nvidia.json; in a container add 'graphics' to NVIDIA_DRIVER_CAPABILITIES)")
    else:
        why = "no NVIDIA EGL vendor found"
    unused = bool(nvidia) or gpu
    if found and egl:
        return GLChoice("egl", "software", f"{why}: rendering in software with EGL ({', '.join(found)})", found,
                        unused)
    if osmesa:
        return GLChoice("osmesa", "software", f"{why} and no usable EGL: rendering in software with OSMesa", found,
                        unused)
    if not egl:
        return GLChoice(None, "none", f"{why} and no OSMesa: MuJoCo's default backend, which renders nothing "
                        "without a display; camera envs and videos fail until libegl1 (with the NVIDIA driver "
                        "or libegl-mesa0) or libosmesa6 is installed", found, unused)
    return GLChoice("egl", "software", f"{why}, no EGL vendor and no OSMesa: rendering will fail until one is "
                    "installed (libegl1 and libegl-mesa0, or libosmesa6)", found, unused)


def _osmesa_found() -> bool:
    import ctypes.util

    return ctypes.util.find_library("OSMesa") is not None


def _egl_found() -> bool:
    """glvnd's ``libEGL.so.1``, which PyOpenGL loads for ``MUJOCO_GL=egl`` (a vendor file alone is not it)."""
    import ctypes.util

    return ctypes.util.find_library("EGL") is not None


_CHOICE: list[GLChoice] = []
_LOGGED: list[bool] = []


def apply(env: MutableMapping[str, str] | None = None) -> GLChoice:
    """Choose the backend and set ``MUJOCO_GL`` in ``env`` (default ``os.environ``) unless the user
    set it or MuJoCo is already imported (its choice is then made). Returns the choice."""
    target = os.environ if env is None else env
    if target.get("MUJOCO_GL") or not sys.platform.startswith("linux") or target.get("DISPLAY") \
            or target.get("WAYLAND_DISPLAY"):
        choice = choose(target)  # nothing to look up: the user's choice or a display
    else:
        vendors = egl_vendors(target)
        egl = _egl_found()  # find_library runs ldconfig: only when the user chose nothing
        osmesa = (not vendors or not egl) and _osmesa_found()
        choice = choose(target, vendors=vendors, osmesa=osmesa, gpu=nvidia_gpu_present(), egl=egl)
    if choice.backend is not None and choice.kind != "user" and "mujoco" not in sys.modules:
        target["MUJOCO_GL"] = choice.backend
    if env is None:
        _CHOICE[:] = [choice]
    return choice


def current() -> GLChoice | None:
    """The choice :func:`apply` made for this process (``None`` before it ran)."""
    return _CHOICE[0] if _CHOICE else None


def log_choice_once(logger: logging.Logger) -> None:
    """Say once per process how MuJoCo renders: a warning when a GPU is left unused, info otherwise."""
    choice = current()
    if _LOGGED or choice is None or choice.kind in ("user", "display"):
        return
    _LOGGED.append(True)
    level = logging.WARNING if choice.gpu_unused or choice.kind == "none" else logging.INFO
    logger.log(level, "MuJoCo renders with MUJOCO_GL=%s: %s (set MUJOCO_GL to choose)", choice.backend, choice.reason)
