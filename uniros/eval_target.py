"""What ``uniros eval`` evaluates: the env ID and model file from what was typed, and when a run's own
``run.json`` may name the env without the user typing it.

A run folder may come from anyone (docs/trust.md): the env its ``run.json`` names is evaluated untyped only
when making it runs no code and drives no robot. An ID that imports a module, a Real ID, or the ID of an
arm file this process has not registered has to be typed (``uniros eval ID RUN``); typed, the run's arm
file registers.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

__all__ = ["eval_target"]


def eval_target(first: str | None, second: str | None, env: str | None,
                note: Callable[[str], None]) -> tuple[str, Path]:
    """The env ID and model file of ``uniros eval`` from what was typed: ``first`` and ``second`` the
    positional arguments (ID MODEL, or MODEL alone), ``env`` the ``--env`` option; ``note`` says which arm
    file a run registered."""
    from uniros.model_files import resolve_model_path, trained_env_id
    from uniros.run_envs import check_env_id
    from uniros.training import TrainingError

    if second is None:  # one positional: a model (or a run directory), or an env ID without its model
        if first is not None and not Path(first).exists() and (":" in first or first.endswith(("-v0", "-v1"))
                                                                 or _registered(first)):
            raise TrainingError(f"give the model to evaluate: uniros eval {first} MODEL (a .zip, or the run "
                                "directory `uniros train` printed)")
        first, second = None, first
    if second is None:
        raise TrainingError("give a model: uniros eval ENV_ID MODEL, uniros eval RUN_DIR, or "
                            "uniros eval MODEL --env ENV_ID")
    typed = env or first
    if typed:
        try:
            check_env_id(typed)
        except TrainingError:  # the ID of the run's own arm file (or its Real twin): the run names the file
            if not _register_run_arm_near(Path(second), typed, note):
                raise
            check_env_id(typed)
    model_path = resolve_model_path(second)
    if not typed:
        _confirm_run_env(model_path, trained_env_id(model_path), second)
        _register_run_arm_near(model_path, None, note)
    env_id = typed or trained_env_id(model_path)
    if env_id is None:
        raise TrainingError(f"cannot tell which env {model_path} was trained on: uniros eval ENV_ID {second}")
    check_env_id(env_id)
    return env_id, model_path


def _confirm_run_env(model: Path, env_id: str | None, given: str) -> None:
    """A run folder may come from anyone: the env its ``run.json`` names is evaluated without being typed only
    when that runs no code and drives no robot (docs/trust.md). An ID that imports a module (``module:ID``),
    a Real ID, or the ID of an arm file this process has not registered (its xacro may run code) has to be
    typed: ``uniros eval ID RUN``."""
    import rl_environments
    from uniros.training import TrainingError

    if env_id is None:
        return
    bare = env_id.rpartition(":")[2]
    meta = (model if model.is_dir() else model.parent) / "run.json"
    try:
        arm_file = json.loads(meta.read_text()).get("arm_file")
    except (OSError, ValueError, AttributeError):
        arm_file = None
    why = None
    if ":" in env_id:
        why = f"imports the module {env_id.rpartition(':')[0]!r} (its code runs)"
    elif bare in rl_environments.REAL_ENV_SPECS:
        why = "drives a real robot"
    elif isinstance(arm_file, str) and arm_file and not _registered(bare) and (
            (meta.parent / arm_file).is_file() if not Path(arm_file).is_absolute() else Path(arm_file).is_file()):
        why = f"comes from the arm file {arm_file} (its xacro may run code)"
    if why is not None:
        raise TrainingError(f"{model}'s run.json names the env {env_id!r}, which {why}: evaluate it by typing the "
                            f"ID yourself, `uniros eval {env_id} {given}`")


def _register_run_arm_near(model: Path, typed: str | None, note: Callable[[str], None]) -> bool:
    """Register the arm file of the run ``model`` belongs to (a run directory, or a model in one), if
    its ``run.json`` names one this process lacks and ``typed`` (the ID given, if any) is the run's ID or
    its Real twin; whether it did."""
    from uniros.run_envs import register_run_arm

    meta = (model if model.is_dir() else model.parent) / "run.json"
    try:
        data = json.loads(meta.read_text())
    except (OSError, ValueError):
        return False
    if not isinstance(data, dict) or not data.get("arm_file"):
        return False
    trained = str(data.get("env_id", "")).rpartition(":")[2]
    if typed is not None and typed.rpartition(":")[2] not in (trained, trained.replace("Sim-v0", "Real-v0")):
        return False
    register_run_arm(data, str(meta), note)
    return True


def _registered(env_id: str) -> bool:
    import gymnasium as gym

    import rl_environments  # noqa: F401 - registers the uniros IDs

    return env_id in gym.registry
