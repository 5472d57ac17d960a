"""Which OpenGL backend MuJoCo renders with, chosen before MuJoCo is first imported.

MuJoCo reads ``MUJOCO_GL`` once, when ``mujoco`` is imported, so ``import multiros`` (which
``uniros`` does first) calls :func:`apply` and never overrides a user's choice. Without one, on a
Linux machine without a display:

* an **NVIDIA EGL vendor** (glvnd's ``egl_vendor.d/10_nvidia.json``, what the NVIDIA driver and
  the NVIDIA container toolkit's ``graphics`` capability install) means ``egl`` on the GPU: camera
  envs and videos render at about 0.6 ms an 84 x 84 frame (H200) instead of tens of ms;
* otherwise rendering is software, said in one log line at the first rendered image: ``egl`` when
  another EGL vendor is installed (Mesa's llvmpipe, the fastest software path), else ``osmesa``
  when libOSMesa is found, else ``egl`` (whose error then names what to install).

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
        kind: ``user`` (``MUJOCO_GL`` was set), ``display``, ``gpu`` (NVIDIA EGL) or ``software``.
        reason: one line saying why.
        vendors: the EGL vendor libraries found (``library_path`` of each vendor file).
    """

    backend: str | None
    kind: str
    reason: str
    vendors: tuple[str, ...] = field(default=())


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
           osmesa: bool = False, gpu: bool = False) -> GLChoice:
    """The backend for ``env`` (see the module docstring); ``vendors``: :func:`egl_vendors`,
    ``osmesa``: libOSMesa found, ``gpu``: :func:`nvidia_gpu_present`."""
    found = tuple(vendors)
    user = env.get("MUJOCO_GL", "").strip()
    if user:
        return GLChoice(user, "user", f"MUJOCO_GL={user} set by the user", found)
    if not platform.startswith("linux"):
        return GLChoice(None, "display", f"MuJoCo's default for {platform}", found)
    if env.get("DISPLAY") or env.get("WAYLAND_DISPLAY"):
        return GLChoice(None, "display", "a display is set: MuJoCo's default (GLFW)", found)
    nvidia = [v for v in found if "nvidia" in v.lower()]
    if nvidia:
        return GLChoice("egl", "gpu", f"NVIDIA EGL vendor ({nvidia[0]}): rendering on the GPU", found)
    if gpu:
        why = ("an NVIDIA GPU is present but no NVIDIA EGL vendor is installed (glvnd's egl_vendor.d has no "
               "10_nvidia.json; in a container add 'graphics' to NVIDIA_DRIVER_CAPABILITIES)")
    else:
        why = "no NVIDIA EGL vendor found"
    if found:
        return GLChoice("egl", "software", f"{why}: rendering in software with EGL ({', '.join(found)})", found)
    if osmesa:
        return GLChoice("osmesa", "software", f"{why} and no EGL vendor: rendering in software with OSMesa", found)
    return GLChoice("egl", "software", f"{why}, no EGL vendor and no OSMesa: rendering will fail until one is "
                    "installed (libegl1 and libegl-mesa0, or libosmesa6)", found)


def _osmesa_found() -> bool:
    import ctypes.util

    return ctypes.util.find_library("OSMesa") is not None


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
        osmesa = not vendors and _osmesa_found()  # find_library runs ldconfig: only when it matters
        choice = choose(target, vendors=vendors, osmesa=osmesa, gpu=nvidia_gpu_present())
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
    level = logging.WARNING if "GPU is present" in choice.reason else logging.INFO
    logger.log(level, "MuJoCo renders with MUJOCO_GL=%s: %s (set MUJOCO_GL to choose)", choice.backend, choice.reason)
