"""``uniros new``: copy a robot-env + task-env template pair into a new package, names filled in.

``create_from_templates("MyArm", Path("."), goal=False, style="multiros")`` writes::

    my_arm/__init__.py            imports the task module, which registers MyArmTaskEnv-v0
    my_arm/my_arm_robot_env.py    class MyArmRobotEnv   (from templates/MyRobotEnv.py)
    my_arm/my_arm_task_env.py     class MyArmTaskEnv    (from templates/MyTaskEnv.py)

Goal templates give ``MyArmRobotGoalEnv``/``MyArmTaskGoalEnv`` (ID ``MyArmTaskGoalEnv-v0``);
FRobs_RL-style ones ``MyArmRobotEnv``/``MyArmTaskEnv`` from ``CustomRobotEnv``/``CustomTaskEnv``.
Existing files are never overwritten: if any target exists, nothing is written.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Literal

Style = Literal["multiros", "frobs"]


class TemplateTargetExistsError(FileExistsError, ValueError):
    """A file ``uniros new`` would create already exists (nothing was written)."""


@dataclass(frozen=True)
class _Pair:
    robot: str  # template class (= file stem)
    task: str


_PAIRS: dict[tuple[str, bool], _Pair] = {
    ("multiros", False): _Pair("MyRobotEnv", "MyTaskEnv"),
    ("multiros", True): _Pair("MyRobotGoalEnv", "MyTaskGoalEnv"),
    ("frobs", False): _Pair("CustomRobotEnv", "CustomTaskEnv"),
}
_NAME = re.compile(r"^[A-Z][A-Za-z0-9]*$")


def template_dir() -> Path:
    """Directory of the shipped templates (``uniros.templates`` installed, or ``templates/`` in a checkout)."""
    try:
        path = Path(str(resources.files("uniros.templates")))
        if (path / "MyRobotEnv.py").is_file():
            return path
    except ModuleNotFoundError:
        pass
    checkout = Path(__file__).resolve().parent.parent / "templates"
    if (checkout / "MyRobotEnv.py").is_file():
        return checkout
    raise FileNotFoundError("uniros templates not found: neither the uniros.templates package nor "
                            f"{checkout} holds MyRobotEnv.py; reinstall uniros")


def snake_case(name: str) -> str:
    """``MyArm`` -> ``my_arm``; ``UR5e`` -> ``ur5e``."""
    return re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", name).lower()


def create_from_templates(name: str, directory: Path, *, goal: bool = False, style: Style = "multiros") -> list[Path]:
    """Create package ``<directory>/<snake name>/`` with a robot env and a task env named after ``name``.

    Args:
        name: the robot's name in CamelCase (``MyArm``); classes become ``MyArmRobotEnv`` and
            ``MyArmTaskEnv`` (``...GoalEnv`` with ``goal``), the env ID ``MyArmTaskEnv-v0``.
        directory: where the package directory is created.
        goal: goal-conditioned (HER-ready) templates.
        style: ``"multiros"`` (``MyRobotEnv``/``MyTaskEnv`` hooks) or ``"frobs"`` (FRobs_RL's
            ``CustomRobotEnv``/``CustomTaskEnv`` hooks; plain envs only, FRobs_RL had no goal env).

    Returns:
        The created files, ``__init__.py`` first.

    Raises:
        ValueError: a bad name, style, or the ``frobs`` style with ``goal``.
        TemplateTargetExistsError: a target file exists (also a ``FileExistsError``); nothing written.
    """
    if not isinstance(name, str) or not _NAME.match(name):
        raise ValueError(f"robot name {name!r} must be CamelCase letters and digits starting with a capital "
                         "(e.g. 'MyArm'); it becomes the class-name prefix")
    if style not in ("multiros", "frobs"):
        raise ValueError(f"template style {style!r} is not 'multiros' or 'frobs'")
    pair = _PAIRS.get((style, bool(goal)))
    if pair is None:
        raise ValueError("FRobs_RL has no goal-conditioned env template; use style='multiros' with goal=True")

    suffix = "GoalEnv" if goal else "Env"
    package = snake_case(name)
    robot_class, task_class = f"{name}Robot{suffix}", f"{name}Task{suffix}"
    robot_module, task_module = f"{package}_robot_env", f"{package}_task_env"
    renames = {pair.robot: robot_class, pair.task: task_class}
    modules = {pair.robot: robot_module, pair.task: task_module}

    source = template_dir()
    root = Path(directory) / package
    files = {
        root / "__init__.py": _package_init(name, task_module, task_class),
        root / f"{robot_module}.py": _fill((source / f"{pair.robot}.py").read_text(), renames, modules, package),
        root / f"{task_module}.py": _fill((source / f"{pair.task}.py").read_text(), renames, modules, package),
    }
    existing = [str(p) for p in files if p.exists()]
    if existing:
        raise TemplateTargetExistsError(f"refusing to overwrite existing file(s): {', '.join(existing)}; "
                                        "choose another name or directory (nothing was written)")
    root.mkdir(parents=True, exist_ok=True)
    created = []
    for path, text in files.items():
        with path.open("x") as fh:  # "x": never clobber a file that appeared meanwhile
            fh.write(text)
        created.append(path)
    return created


def _fill(text: str, classes: dict[str, str], modules: dict[str, str], package: str) -> str:
    for old, new in modules.items():
        text = re.sub(rf"from \.{old} import", f"from .{new} import", text)
        text = text.replace(f"``{old}.py``", f"``{new}.py``")
    for old, new in classes.items():
        text = re.sub(rf"\b{old}\b", new, text)
    text = re.sub(r"\bmy_robot\b", package, text)
    return text.replace("(template)", f"(created by `uniros new` for {package})", 1)


def _package_init(name: str, task_module: str, task_class: str) -> str:
    return (
        f'"""{name} robot and task environments (created by ``uniros new``).\n\n'
        f"Importing this package registers ``{task_class}-v0``.\n"
        '"""\n\n'
        f"from .{task_module} import ENV_ID, {task_class}\n\n"
        f'__all__ = ["ENV_ID", "{task_class}"]\n'
    )
