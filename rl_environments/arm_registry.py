"""Arms as data: gymnasium IDs from arm files (:mod:`rl_environments.arm_file`).

``register_arm(path)`` checks an arm file and registers the IDs the tasks of the task table
(:data:`rl_environments.env_ids.TASKS`) give it: ``<NAME>ReacherSim-v0``, ``<NAME>ReacherGoalSim-v0``,
``<NAME>SlideSim-v0``, ``<NAME>SlideGoalSim-v0`` and, for an arm with a gripper, ``<NAME>PushSim-v0``,
``<NAME>PushGoalSim-v0``, ``<NAME>PnPSim-v0``, ``<NAME>PnPGoalSim-v0``, each with its ``...Real-v0`` twin.
Each ID is an arm env class (:mod:`rl_environments.arm_env`) made with keyword arguments (``arm=<NAME>``,
``task=<task>``); :func:`arm_value` gives the arm as a value. The arm files named by ``UNIROS_ARMS``
(paths separated by ``os.pathsep``) are registered
when ``rl_environments`` is imported, so ``uniros train``/``eval``, rl-zoo3 and worker processes see
them; ``register_arm`` adds its file to that variable for the processes this one starts.

Nothing is registered half-way: a file is checked whole (keys, the description's links and joints)
before any ID is.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import Any

from multiros.excerpt import error_line
from rl_environments.arm import _urdf_text, chain_of, top_down_ik_of
from rl_environments.arm_file import ArmFile, ArmFileError, load_arm_file

__all__ = ["arm_env_ids", "arm_of", "arm_value", "env_arm_paths", "chain_of", "check_description", "env_arm_errors",
           "register_arm", "register_env_arms", "registered_arms", "top_down_ik_of", "unregister_arm"]

_ARMS: dict[str, ArmFile] = {}
_ENV_ARM_ERRORS: dict[str, str] = {}  # UNIROS_ARMS entries skipped at import: path -> why
_ADDED_TO_ENVIRONMENT: set[str] = set()  # the UNIROS_ARMS entries register_arm added (unregister takes them out)


def arm_env_ids(spec: ArmFile) -> dict[str, tuple[str, str, str]]:
    """``{sim ID: (task infix, the env's earlier class name, real ID)}`` of an arm file (the tasks that need
    a gripper only with one)."""
    from rl_environments.env_ids import TASKS, arm_task_ids

    out = {}
    for sim_id, (task, goal, real_id) in arm_task_ids(spec.name, gripper=spec.gripper is not None).items():
        infix = f"{TASKS[task].infix}{'Goal' if goal else ''}"
        out[sim_id] = (infix, f"{spec.name}{infix}Env", real_id)
    return out


_VALUES: dict[str, Any] = {}


def arm_value(name: str) -> Any:
    """The registered arm ``name`` as an :class:`~rl_environments.arm.Arm` (one per registration)."""
    from rl_environments.arm import Arm

    spec = arm_of(name)
    value = _VALUES.get(name)
    if value is None or value.file is not spec:
        value = _VALUES[name] = Arm(spec)
    return value


def check_description(spec: ArmFile) -> None:
    """The file's joints and links against its description: the chain exists and is the arm's joints."""
    try:
        chain = chain_of(spec)
    except ArmFileError:
        raise
    except ValueError as exc:  # a link that is not there, or no chain between them
        msg = error_line(exc)
        key = ("arm.ee_link" if "tip_link" in msg or "no kinematic chain" in msg else
               "arm.base_link" if msg.startswith("base_link") else
               "arm.joints" if "joint" in msg else "description.uri")
        raise ArmFileError(f"{spec.path}: key {key!r}: {msg}") from None
    except Exception as exc:  # xacro, a missing package, a broken URDF: one line naming the file and key
        raise ArmFileError(f"{spec.path}: key 'description.uri' ({spec.description_uri}): {error_line(exc)}") \
            from None
    if tuple(chain.joint_names) != spec.joints:
        raise ArmFileError(
            f"{spec.path}: key 'arm.joints' {list(spec.joints)} are not the moving joints from "
            f"{spec.base_link!r} to {spec.ee_link!r} in the description, which are {list(chain.joint_names)}")
    if spec.gripper is not None:
        _check_gripper(spec)


def _check_gripper(spec: ArmFile) -> None:
    """The gripper's joints are movable joints of the description; the commanded one mimics nothing."""
    import xml.etree.ElementTree as ET

    assert spec.gripper is not None
    root = ET.fromstring(_urdf_text(spec.description_uri, tuple(sorted(spec.xacro_args.items()))))
    joints = {j.get("name"): j for j in root.findall("joint")}  # not the <ros2_control> ones
    for i, name in enumerate(spec.gripper.joints):
        joint = joints.get(name)
        if joint is None:
            raise ArmFileError(f"{spec.path}: key 'gripper.joints': {name!r} is not a joint of the description")
        if joint.get("type") not in ("revolute", "prismatic", "continuous"):
            raise ArmFileError(f"{spec.path}: key 'gripper.joints': {name!r} is a {joint.get('type')} joint, not "
                               "an actuated one: name the finger joints (prismatic or revolute)")
        if i == 0 and joint.find("mimic") is not None:
            raise ArmFileError(f"{spec.path}: key 'gripper.joints': {name!r} mimics another joint; the first "
                               "finger joint is the commanded one (put the mimicking one second)")
        if i == 1 and spec.gripper.independent and joint.find("mimic") is not None:
            raise ArmFileError(f"{spec.path}: key 'gripper.independent': {name!r} mimics another joint, so it is "
                               "not driven: set independent: false")


def register_arm(path: str | os.PathLike[str], *, replace: bool = False, check_chain: bool = True,
                 tell_children: bool = True) -> list[str]:
    """Register an arm file's IDs with gymnasium and return them (simulated, then the Real twins).

    Args:
        path: the arm file.
        replace: re-register an arm of the same name from the same file (after editing it).
        check_chain: load the description and check the chain now (the shipped arms skip it at
            import: their files are checked by the tests).
        tell_children: add the file to ``UNIROS_ARMS`` for the processes this one starts (the shipped
            arms need not: every process registers them).

    Raises:
        ArmFileError: the file does not check, its description does not hold its chain, or another
            file already registered an arm of that name (or a shipped ID has it).
    """
    from gymnasium.envs.registration import registry

    from rl_environments import env_ids

    spec = load_arm_file(path)
    ids = arm_env_ids(spec)
    previous = _ARMS.get(spec.name)
    if previous is not None and not (replace or previous.path == spec.path):
        raise ArmFileError(f"{spec.path}: key 'name' {spec.name!r} is already registered by {previous.path}: "
                           "give one of the arms another name")
    if previous is None:
        clash = [i for i in ids if i in registry or ids[i][2] in registry]
        if clash:
            raise ArmFileError(f"{spec.path}: key 'name' {spec.name!r} gives ID {clash[0]!r}, which is already "
                               "registered: give the arm another name")
    if check_chain:
        check_description(spec)
    if previous is not None:
        unregister_arm(spec.name)
    _ARMS[spec.name] = spec
    out: list[str] = []
    for sim_id, (task, goal, real_id) in env_ids.arm_task_ids(spec.name, gripper=spec.gripper is not None).items():
        env_ids.note_arm_ids(spec.name, sim_id, real_id, task=task, goal=goal)
        out.append(sim_id)
    env_ids.register_envs()  # the new rows with gymnasium, as every ID is
    out += [ids[i][2] for i in ids]
    if tell_children:
        _remember_in_environment(spec.path)
    return out


def unregister_arm(name: str) -> None:
    """Remove an arm's IDs (its env classes are rebuilt if it is registered again)."""
    from gymnasium.envs.registration import registry

    from rl_environments import env_ids

    spec = _ARMS.pop(name, None)
    _VALUES.pop(name, None)
    if spec is None:
        return
    for sim_id, (_, _, real_id) in arm_env_ids(spec).items():
        registry.pop(sim_id, None)
        registry.pop(real_id, None)
        env_ids.forget_arm_ids(sim_id, real_id)
    if str(spec.path) in _ADDED_TO_ENVIRONMENT:
        import json

        _ADDED_TO_ENVIRONMENT.discard(str(spec.path))
        kept = [p for p in os.environ.get("UNIROS_ARMS", "").split(os.pathsep) if p and p != str(spec.path)]
        os.environ["UNIROS_ARMS"] = os.pathsep.join(kept)
        if ARMS_JSON_VARIABLE in os.environ:
            os.environ[ARMS_JSON_VARIABLE] = json.dumps([p for p in _json_paths() if p != str(spec.path)])


#: Arm files for child processes whose paths hold ``os.pathsep`` (``UNIROS_ARMS`` cannot carry them): a JSON list.
ARMS_JSON_VARIABLE = "UNIROS_ARMS_JSON"


def _json_paths() -> list[str]:
    import json

    try:
        value = json.loads(os.environ.get(ARMS_JSON_VARIABLE) or "[]")
    except ValueError:
        return []
    return [p for p in value if isinstance(p, str) and p] if isinstance(value, list) else []


def _remember_in_environment(path: Path) -> None:
    """Add the file to ``UNIROS_ARMS`` so processes started from here (workers, child nodes) have it; a path
    that holds ``os.pathsep`` (``:``) goes to ``UNIROS_ARMS_JSON`` instead, where no separator splits it."""
    import json

    text = str(path)
    current = [p for p in os.environ.get("UNIROS_ARMS", "").split(os.pathsep) if p]
    if os.pathsep in text:
        listed = _json_paths()
        if text not in listed:
            os.environ[ARMS_JSON_VARIABLE] = json.dumps([*listed, text])
            _ADDED_TO_ENVIRONMENT.add(text)
    elif text not in current:
        os.environ["UNIROS_ARMS"] = os.pathsep.join([*current, text])
        _ADDED_TO_ENVIRONMENT.add(text)


def registered_arms() -> dict[str, ArmFile]:
    """The registered arm files by name (shipped and the user's)."""
    return dict(_ARMS)


def arm_of(name: str) -> ArmFile:
    """A registered arm file by name."""
    try:
        return _ARMS[name]
    except KeyError:
        raise ArmFileError(f"no arm {name!r} is registered; arms: {sorted(_ARMS)}") from None


def env_arm_paths() -> list[str]:
    """The arm files this process's environment names: ``UNIROS_ARMS``'s, then ``UNIROS_ARMS_JSON``'s."""
    return [p.strip() for p in os.environ.get("UNIROS_ARMS", "").split(os.pathsep) if p.strip()] + _json_paths()


def register_env_arms(paths: str | None = None, *, strict: bool = True) -> list[str]:
    """Register the arm files of ``UNIROS_ARMS`` and ``UNIROS_ARMS_JSON`` (or ``paths``, separated by
    ``os.pathsep``); the IDs.

    Args:
        strict: raise :class:`ArmFileError` on the first file that cannot be registered. Otherwise (at
            import) each such file is skipped with one line logged, the others are registered, and
            :func:`env_arm_errors` says what was skipped (``uniros.make`` of a missing ID names it).
    """
    text = os.environ.get("UNIROS_ARMS", "") if paths is None else paths
    out: list[str] = []
    items = [*text.split(os.pathsep), *(_json_paths() if paths is None else [])]
    for item in items:
        if item.strip():
            path = Path(item.strip()).expanduser()
            if not any(spec.path == path.resolve() for spec in _ARMS.values()):  # not registered yet
                try:
                    out += register_arm(path)
                except ArmFileError as exc:
                    message = f"UNIROS_ARMS: {exc}"
                    if strict:
                        raise ArmFileError(message) from None
                    _ENV_ARM_ERRORS[str(path)] = message
                    logging.getLogger("rl_environments.arm_registry").warning(
                        "%s (its IDs are not registered)", message)
                else:
                    _ENV_ARM_ERRORS.pop(str(path), None)
    return out


def env_arm_errors() -> list[str]:
    """Why ``UNIROS_ARMS`` entries were skipped (one line each; empty when every one registered)."""
    return list(_ENV_ARM_ERRORS.values())
