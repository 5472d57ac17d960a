"""SpawnEntity handling of the simulation node: request checks, URI options, the source policy.

:func:`spawn_entity` validates the request (resource, namespace, pose, sizes), splits the URI's
query into xacro arguments and the node's own options (``__controllers``, ``__controllers_file``,
``__joint_positions``: ``name=value,...``, the pose the robot is spawned and reset at), loads the
description outside the world under the node's :class:`~multiros.sim.description.SourcePolicy` and
limits, compiles and admits it beside the world (:mod:`multiros.sim.world_prepare`: the others step
meanwhile), commits it under the node's lock (or,
when the world changed structure meanwhile, spawns and admits it under the lock as before) and
attaches the robot's ROS interfaces. The node's entity limits and the caller's quota
(:mod:`multiros.sim.node_quota`) are checked before loading, after loading, and under the lock before
the compile and again at the commit; a client whose spawns the world keeps refusing waits out a
cool-down before its next one is loaded. :func:`entity_name` picks the name (``allow_renaming``).
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING, Any
from urllib.parse import parse_qsl, urlsplit

import numpy as np

from multiros.sim import convert
from multiros.sim.description import SourcePolicy, UnsupportedFormatError, load_description
from multiros.sim.errors import ControllerError, DescriptionError, EntityError, SpawnRefusedError
from multiros.sim.node_quota import describe_caller
from multiros.sim.node_results import FAILED, fail, ok
from multiros.sim.world_types import EntityCategory, default_category

if TYPE_CHECKING:
    from multiros.sim.node import SimulationNode
    from multiros.sim.node_quota import EntityQuota
    from multiros.sim.world import World

_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_NAMESPACE = re.compile(r"^(/[A-Za-z_][A-Za-z0-9_]*)*/?$")
_MAX_URI = 8192  # characters of entity_resource.uri


def spawn_entity(node: SimulationNode, request: Any, response: Any, policy: SourcePolicy | None, *,
                 caller: str | None = None, limited: bool = True) -> Any:
    """SpawnEntity on ``node`` for ``caller``. ``policy`` None trusts the request (the node's own
    command line); ``limited`` False skips the entity limits and quotas (the node's owner)."""
    res = response.result
    uri, text = request.entity_resource.uri, request.entity_resource.resource_string
    if not uri and not text:
        fail(res, response.NO_RESOURCE, "both entity_resource.uri and resource_string are empty")
        return response
    namespace = request.entity_namespace
    if namespace and not _NAMESPACE.match(namespace if namespace.startswith("/") else "/" + namespace):
        fail(res, response.NAMESPACE_INVALID, f"namespace {namespace!r} is not a valid ROS namespace")
        return response
    frame = request.initial_pose.header.frame_id
    if frame not in ("", "world"):
        fail(res, FAILED, f"initial_pose frame {frame!r} is not supported; use 'world' (or empty)")
        return response
    position, quat = convert.pose_to_arrays(request.initial_pose.pose)
    problem = convert.validate_quaternion(quat) or (
        None if np.all(np.isfinite(position)) else f"position {position.tolist()} is not finite"
    )
    if problem:
        fail(res, response.INVALID_POSE, problem)
        return response
    quota = node.entity_quota if limited else None
    if quota is not None:
        waiting = quota.cooling_down(caller)
        if waiting is not None:
            fail(res, FAILED, waiting)
            return response
        if _refused(node, quota, caller, None, res):
            return response
    limits = node.description_limits
    if len(uri) > _MAX_URI or len(text) > limits.max_chars:
        what = "entity_resource.uri" if len(uri) > _MAX_URI else "entity_resource.resource_string"
        most = _MAX_URI if len(uri) > _MAX_URI else limits.max_chars
        fail(res, response.RESOURCE_PARSE_ERROR, f"{what} is longer than {most} characters (the node's limit)")
        return response
    description: str = text
    args: dict[str, str] = {}
    if uri:
        parts = urlsplit(uri)
        if parts.query:
            args = dict(parse_qsl(parts.query, keep_blank_values=True))
            uri = parts._replace(query="").geturl()
        if parts.scheme != "string":  # "string:?opts" = options for the resource_string
            description = uri
    controllers_yaml: Any = args.pop("__controllers_file", None)
    controllers = [c for c in args.pop("__controllers", "").split(",") if c] or None
    try:
        joint_positions = _joint_positions(args.pop("__joint_positions", ""))
    except ValueError as exc:
        fail(res, response.INVALID_POSE, str(exc))
        return response
    try:
        if controllers_yaml:
            controllers_yaml = (policy.resolve(controllers_yaml, node.world.index, what="controllers file")
                                if policy is not None else node.world.index.resolve_uri(controllers_yaml))
        # Parsed outside the world: a refused or out-of-bounds description never touches it.
        desc = load_description(description, args=args or None, index=node.world.index,
                                mesh_cache=node.world.mesh_cache,
                                default_armature=node.world.options.default_armature, policy=policy,
                                limits=limits)
    except UnsupportedFormatError as exc:
        fail(res, response.UNSUPPORTED_FORMAT, str(exc))
        return response
    except DescriptionError as exc:
        code = response.MISSING_ASSETS if exc.missing_assets else response.RESOURCE_PARSE_ERROR
        fail(res, code, str(exc))
        return response
    except (RecursionError, MemoryError) as exc:
        fail(res, response.RESOURCE_PARSE_ERROR, f"the description is too large or too deep to load "
              f"({type(exc).__name__}); see the node's description limits")
        return response
    if joint_positions:
        unknown = sorted(set(joint_positions) - {j.name for j in desc.joints})
        if unknown:
            fail(res, response.INVALID_POSE, f"__joint_positions names joint(s) {unknown[:10]} the description does "
                                             f"not have; its joints: {[j.name for j in desc.joints][:30]}")
            return response
    robot = default_category(desc) == EntityCategory.ROBOT  # as the world will file it (no category asked)
    if quota is not None and _refused(node, quota, caller, robot, res):
        return response
    with node.lock:
        if quota is not None:
            quota.prune(set(node.world.entity_names()))
            if _refused(node, quota, caller, robot, res):
                return response
        name = entity_name(node.world, request.name, request.allow_renaming, response)
        if name is None:
            return response
        snapshot = node.world.spawn_snapshot(name)
    spawn = {"pose": (position, quat), "namespace": namespace or None, "controllers": controllers,
             "controllers_yaml": controllers_yaml, "joint_positions": joint_positions}
    try:  # compiled and admitted beside the world, the others stepping meanwhile (multiros.sim.world_prepare)
        prepared = node.world.prepare_spawn(snapshot, desc, limits=limits, **spawn)
    except (DescriptionError, EntityError, ControllerError, ValueError, SpawnRefusedError) as exc:
        return _spawn_failed(node, quota, caller, response, name, exc)
    with node.lock:
        if quota is not None and _refused(node, quota, caller, robot, res):
            return response
        try:
            info = node.world.commit_spawn(prepared) if prepared is not None else None
        except (DescriptionError, EntityError, ControllerError, ValueError) as exc:  # as in the trial: not seen
            return _spawn_failed(node, quota, caller, response, name, exc)
        if info is None:  # the world changed structure meanwhile: compile and admit under the lock
            name = entity_name(node.world, request.name, request.allow_renaming, response)
            if name is None:
                return response
            try:
                info = node.world.spawn(name, desc, **spawn)
            except (DescriptionError, EntityError, ControllerError, ValueError) as exc:
                return _spawn_failed(node, quota, caller, response, name, exc)
            try:  # before any step: refused, it never touched the others
                node.world.admit(info.name, limits)
            except SpawnRefusedError as exc:
                node.world.delete(info.name)
                return _spawn_failed(node, quota, caller, response, name, exc)
        try:
            node._attach_robot(info.name)
        except Exception as exc:
            node.world.delete(info.name)
            fail(res, FAILED, f"spawned {info.name!r} but could not create its ROS interfaces: {exc}")
            return response
        if quota is not None:
            quota.record(info.name, caller, robot)
            quota.note_admitted(caller)
    response.entity_name = info.name
    ok(res)
    return response


_MAX_JOINT_POSITIONS = 256  # entries of __joint_positions: more than any robot the limits admit has joints


def _joint_positions(text: str) -> dict[str, float] | None:
    """``__joint_positions``: ``name=value`` pairs, comma-separated (hostile: bounded, names checked,
    values finite; unknown joints and values outside the limits are the world's errors)."""
    if not text:
        return None
    items = text.split(",")
    if len(items) > _MAX_JOINT_POSITIONS:
        raise ValueError(f"__joint_positions has {len(items)} entries; at most {_MAX_JOINT_POSITIONS}")
    out: dict[str, float] = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not _JOINT_NAME.fullmatch(name):
            raise ValueError(f"__joint_positions entry {item[:80]!r} is not NAME=NUMBER")
        try:
            number = float(value)
        except ValueError:
            raise ValueError(f"__joint_positions entry {item[:80]!r} is not NAME=NUMBER") from None
        if not np.isfinite(number):
            raise ValueError(f"__joint_positions: joint {name!r} position {value[:40]!r} is not finite")
        out[name] = number
    return out


_JOINT_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_/.\-]{0,255}")


def _spawn_failed(node: SimulationNode, quota: EntityQuota | None, caller: str | None, response: Any, name: str,
                  exc: Exception) -> Any:
    """The reply to a spawn the world could not take (the world is as before); all but a name
    conflict count as refusals by the world against ``caller``."""
    res = response.result
    if isinstance(exc, EntityError):
        fail(res, response.NAME_INVALID, str(exc))
        return response
    if isinstance(exc, DescriptionError):
        fail(res, response.MISSING_ASSETS if exc.missing_assets else response.RESOURCE_PARSE_ERROR, str(exc))
    elif isinstance(exc, ControllerError):
        fail(res, FAILED, f"controllers of {name!r}: {exc}")
    elif isinstance(exc, SpawnRefusedError):
        fail(res, response.RESOURCE_PARSE_ERROR if exc.reason == "unstable" else response.INVALID_POSE, str(exc))
    else:
        fail(res, response.INVALID_POSE, str(exc))
    return _world_refused(node, quota, caller, response)


def _world_refused(node: SimulationNode, quota: EntityQuota | None, caller: str | None, response: Any) -> Any:
    """The world refused the spawn (``response``'s result set): count it against ``caller``; say so
    once when that starts a cool-down."""
    if quota is not None:
        pause = quota.note_refused(caller, response.result.error_message)
        if pause is not None:
            node.get_logger().warning(
                "%s: %s spawns refused by the world in a row; its spawns wait %.0f s (the last: %s)",
                describe_caller(caller), quota.refusals(caller), pause, response.result.error_message[:200])
    return response


def _refused(node: SimulationNode, quota: EntityQuota, caller: str | None, robot: bool | None, res: Any) -> bool:
    """Whether the node's limits or the caller's quota refuse the spawn (the result is then set)."""
    problem = quota.refusal(caller, robot, set(node.world.entity_names()), len(node._robots))
    if problem is not None:
        fail(res, FAILED, problem)
    return problem is not None


def entity_name(world: World, name: str, allow_renaming: bool, response: Any) -> str | None:
    """The name to spawn under (renamed when allowed), or None with the reply's result set."""
    res = response.result
    if name and not _NAME.match(name):
        if not allow_renaming:
            fail(res, response.NAME_INVALID, f"entity name {name!r} must match [A-Za-z_][A-Za-z0-9_]*")
            return None
        name = re.sub(r"[^A-Za-z0-9_]", "_", name) or "entity"
    if not name:
        if not allow_renaming:
            fail(res, response.NAME_INVALID, "entity name is empty and allow_renaming is false")
            return None
        name = "entity"
    if world.has_entity(name):
        if not allow_renaming:
            fail(res, response.NAME_NOT_UNIQUE, f"an entity named {name!r} exists; pick another name")
            return None
        base, i = name, 1
        while world.has_entity(f"{base}_{i}"):
            i += 1
        name = f"{base}_{i}"
    return name
