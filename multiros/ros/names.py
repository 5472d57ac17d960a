"""ROS 2 name validation, expansion and remapping (the rules of rcl and rmw).

Hand-written: the rules are small and there is no PyPI package implementing them without rclpy.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field

import yaml

from multiros.ros.exceptions import (
    InvalidNamespaceException,
    InvalidNodeNameException,
    InvalidServiceNameException,
    InvalidTopicNameException,
    NameValidationException,
)

__all__ = [
    "validate_node_name",
    "validate_namespace",
    "validate_full_topic_name",
    "expand_topic_name",
    "resolve_name",
    "normalize_namespace",
    "RemapRule",
    "RosArguments",
    "split_ros_arguments",
    "parse_ros_arguments",
]

MAX_NAME_LENGTH = 255
_TOKEN_CHARS = re.compile(r"[A-Za-z0-9_]")
_SUBSTITUTION = re.compile(r"\{(node|ns|namespace)\}")


def _first_bad_char(text: str, allowed: str = "") -> int | None:
    for i, ch in enumerate(text):
        if ch in allowed:
            continue
        if not _TOKEN_CHARS.fullmatch(ch):
            return i
    return None


def validate_node_name(name: str) -> str:
    """Check a node name (``[A-Za-z_][A-Za-z0-9_]*``) and return it.

    Raises:
        InvalidNodeNameException: the name is empty, too long, or has a bad character.
    """
    if not isinstance(name, str) or not name:
        raise InvalidNodeNameException(str(name), "node name must not be empty")
    bad = _first_bad_char(name)
    if bad is not None:
        raise InvalidNodeNameException(name, "node names may contain only letters, digits and '_'", bad)
    if name[0].isdigit():
        raise InvalidNodeNameException(name, "node name must not start with a digit", 0)
    if len(name) > MAX_NAME_LENGTH:
        raise InvalidNodeNameException(name, f"longer than {MAX_NAME_LENGTH} characters")
    return name


def normalize_namespace(namespace: str | None) -> str:
    """Make a namespace absolute (``''``/``None`` -> ``'/'``, ``'robot'`` -> ``'/robot'``) and validate it."""
    if not namespace:
        return "/"
    if not namespace.startswith("/"):
        namespace = "/" + namespace
    return validate_namespace(namespace)


def validate_namespace(namespace: str) -> str:
    """Check an absolute namespace such as ``/`` or ``/robot1/arm``.

    Raises:
        InvalidNamespaceException: the namespace is malformed.
    """
    if not namespace.startswith("/"):
        raise InvalidNamespaceException(namespace, "namespace must be absolute (start with '/')", 0)
    if namespace == "/":
        return namespace
    if namespace.endswith("/"):
        raise InvalidNamespaceException(namespace, "namespace must not end with '/'", len(namespace) - 1)
    _check_tokens(namespace, InvalidNamespaceException)
    return namespace


def _check_tokens(name: str, exc: type[NameValidationException]) -> None:
    bad = _first_bad_char(name, allowed="/")
    if bad is not None:
        raise exc(name, "may contain only letters, digits, '_' and '/'", bad)
    pos = 0
    for token in name.split("/"):
        if pos > 0 and token == "":
            raise exc(name, "must not contain '//' or end with '/'", pos - 1)
        if token and token[0].isdigit():
            raise exc(name, "a name token must not start with a digit", pos)
        pos += len(token) + 1


def validate_full_topic_name(name: str, *, is_service: bool = False) -> str:
    """Check a fully qualified (expanded) topic or service name.

    Raises:
        InvalidTopicNameException, InvalidServiceNameException: the name is malformed.
    """
    exc = InvalidServiceNameException if is_service else InvalidTopicNameException
    if not name.startswith("/"):
        raise exc(name, "a fully qualified name must start with '/'", 0)
    if name == "/":
        raise exc(name, "a name must not be just '/'", 0)
    if name.endswith("/"):
        raise exc(name, "must not end with '/'", len(name) - 1)
    _check_tokens(name, exc)
    if len(name) > MAX_NAME_LENGTH:
        raise exc(name, f"longer than {MAX_NAME_LENGTH} characters")
    return name


def expand_topic_name(name: str, node_name: str, namespace: str, *, is_service: bool = False) -> str:
    """Expand a relative, absolute or private (``~``) name to a fully qualified one.

    ``{node}`` and ``{ns}``/``{namespace}`` substitutions are applied as rcl does.

    Raises:
        InvalidTopicNameException, InvalidServiceNameException: the name is malformed.
    """
    exc = InvalidServiceNameException if is_service else InvalidTopicNameException
    if not isinstance(name, str) or not name:
        raise exc(str(name), "must not be empty")
    fqn_node = namespace.rstrip("/") + "/" + node_name
    if name.startswith("~"):
        if name == "~":
            name = fqn_node
        elif name.startswith("~/"):
            name = fqn_node + name[1:]
        else:
            raise exc(name, "'~' must be followed by '/' (private names are '~/name')", 1)
    if "~" in name:
        raise exc(name, "'~' is only allowed at the start", name.index("~"))

    def _sub(m: re.Match[str]) -> str:
        return node_name if m.group(1) == "node" else namespace.rstrip("/")

    name = _SUBSTITUTION.sub(_sub, name)
    if "{" in name or "}" in name:
        bad = name.index("{" if "{" in name else "}")
        raise exc(name, "unknown substitution (only {node}, {ns}, {namespace})", bad)
    if not name.startswith("/"):
        name = namespace.rstrip("/") + "/" + name
    return validate_full_topic_name(name, is_service=is_service)


@dataclass(frozen=True)
class RemapRule:
    """One ``from:=to`` rule, optionally only for one node (``node:from:=to``)."""

    match: str
    replacement: str
    node: str | None = None


@dataclass
class RosArguments:
    """What ``--ros-args`` carried: remaps, parameters, parameter files, enclave, log level."""

    remaps: list[RemapRule] = field(default_factory=list)
    parameters: dict[str, object] = field(default_factory=dict)
    node_parameters: dict[str, dict[str, object]] = field(default_factory=dict)
    params_files: list[str] = field(default_factory=list)
    enclave: str | None = None
    log_level: str | None = None

    def extend(self, other: RosArguments) -> RosArguments:
        """A new set with ``other``'s rules after (lower priority than) these."""
        merged = RosArguments(
            remaps=self.remaps + other.remaps,
            parameters={**other.parameters, **self.parameters},
            node_parameters={**other.node_parameters, **self.node_parameters},
            params_files=other.params_files + self.params_files,
            enclave=self.enclave or other.enclave,
            log_level=self.log_level or other.log_level,
        )
        return merged

    def node_name_for(self, node_name: str) -> str:
        """The node name after ``__node:=``/``__name:=`` remaps."""
        for rule in self.remaps:
            if rule.match in ("__node", "__name") and rule.node in (None, node_name):
                return validate_node_name(rule.replacement)
        return node_name

    def namespace_for(self, node_name: str, namespace: str) -> str:
        """The namespace after ``__ns:=`` remaps."""
        for rule in self.remaps:
            if rule.match == "__ns" and rule.node in (None, node_name):
                return normalize_namespace(rule.replacement)
        return namespace

    def remap_name(self, resolved: str, node_name: str, namespace: str, *, is_service: bool = False) -> str:
        """Apply the first matching topic/service remap rule to an expanded name."""
        for rule in self.remaps:
            if rule.match.startswith("__") or rule.node not in (None, node_name):
                continue
            try:
                match = expand_topic_name(rule.match, node_name, namespace, is_service=is_service)
            except NameValidationException:
                continue
            if match == resolved:
                return expand_topic_name(rule.replacement, node_name, namespace, is_service=is_service)
        return resolved


def resolve_name(
    name: str,
    node_name: str,
    namespace: str,
    arguments: RosArguments | None = None,
    *,
    is_service: bool = False,
) -> str:
    """Expand ``name`` for a node and apply remapping, as ``rcl_resolve_name`` does."""
    expanded = expand_topic_name(name, node_name, namespace, is_service=is_service)
    if arguments is None:
        return expanded
    return arguments.remap_name(expanded, node_name, namespace, is_service=is_service)


def _parse_value(text: str) -> object:
    # ROS parses -p values as YAML (so "1" -> 1, "[1, 2]" -> list, "true" -> True).
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError:
        return text


def split_ros_arguments(args: Sequence[str]) -> tuple[list[str], list[str]]:
    """``(the program's own arguments, the --ros-args sections)`` of a command line, as rcl splits
    it: a section runs from ``--ros-args`` to ``--`` or the end; the ``--ros-args`` markers stay in
    the second list (``--`` does not), so it can be handed to rcl or :func:`parse_ros_arguments`."""
    own: list[str] = []
    ros: list[str] = []
    in_ros = False
    for arg in args:
        if arg == "--ros-args":
            in_ros = True
            ros.append(arg)
        elif arg == "--" and in_ros:
            in_ros = False
        elif in_ros:
            ros.append(arg)
        else:
            own.append(arg)
    return own, ros


def parse_ros_arguments(args: list[str] | None) -> RosArguments:
    """Parse the ``--ros-args ... [--]`` sections of a command line.

    Arguments outside ``--ros-args`` sections belong to the user and are ignored.

    Raises:
        ValueError: a flag lacks its value or a rule is malformed (the message names it).
    """
    result = RosArguments()
    if not args:
        return result
    i, in_ros = 0, False
    while i < len(args):
        arg = args[i]
        if arg == "--ros-args":
            in_ros = True
        elif arg == "--" and in_ros:
            in_ros = False
        elif in_ros:
            if arg in ("-r", "--remap", "-p", "--param", "--params-file", "-e", "--enclave", "--log-level"):
                if i + 1 >= len(args):
                    raise ValueError(f"ROS argument '{arg}' needs a value")
                value = args[i + 1]
                i += 1
                if arg in ("-r", "--remap"):
                    result.remaps.append(_parse_remap(value))
                elif arg in ("-p", "--param"):
                    key, sep, raw = value.partition(":=")
                    if not sep or not key:
                        raise ValueError(f"parameter argument '{value}' must look like name:=value")
                    node, _, pname = key.rpartition(":")
                    if node:
                        result.node_parameters.setdefault(node, {})[pname] = _parse_value(raw)
                    else:
                        result.parameters[pname] = _parse_value(raw)
                elif arg == "--params-file":
                    result.params_files.append(value)
                elif arg in ("-e", "--enclave"):
                    result.enclave = value
                else:
                    result.log_level = value
            elif ":=" in arg:
                # rcl accepts bare remap rules inside --ros-args too (deprecated form).
                result.remaps.append(_parse_remap(arg))
        i += 1
    return result


def _parse_remap(rule: str) -> RemapRule:
    lhs, sep, rhs = rule.partition(":=")
    if not sep or not lhs or not rhs:
        raise ValueError(f"remap rule '{rule}' must look like from:=to (or node:from:=to)")
    node: str | None = None
    if ":" in lhs:
        node, _, lhs = lhs.partition(":")
    return RemapRule(lhs, rhs, node)
