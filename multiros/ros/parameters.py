"""Node parameters: ``Parameter``, descriptors, the per-node store, and ROS 2 parameter YAML files.

YAML files use the ROS 2 layout::

    /**:                       # every node (also "**", "/ns/*", "/ns/node", "node")
      ros__parameters:
        use_sim_time: true
        arm: {kp: 10.0}        # nested keys become "arm.kp"
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from enum import IntEnum
from pathlib import Path
from typing import Any

import yaml

from multiros.ros.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    ParameterAlreadyDeclaredException,
    ParameterNotDeclaredException,
)

__all__ = [
    "Parameter",
    "ParameterDescriptor",
    "SetParametersResult",
    "ParameterStore",
    "load_parameter_file",
    "parameters_from_yaml",
]


class _Type(IntEnum):
    NOT_SET = 0
    BOOL = 1
    INTEGER = 2
    DOUBLE = 3
    STRING = 4
    BYTE_ARRAY = 5
    BOOL_ARRAY = 6
    INTEGER_ARRAY = 7
    DOUBLE_ARRAY = 8
    STRING_ARRAY = 9

    @classmethod
    def from_parameter_value(cls, value: Any) -> _Type:
        """The parameter type of a Python value.

        Raises:
            TypeError: the value has no ROS parameter type.
        """
        if value is None:
            return cls.NOT_SET
        if isinstance(value, bool):
            return cls.BOOL
        if isinstance(value, int):
            return cls.INTEGER
        if isinstance(value, float):
            return cls.DOUBLE
        if isinstance(value, str):
            return cls.STRING
        if isinstance(value, (bytes, bytearray)):
            return cls.BYTE_ARRAY
        if isinstance(value, (list, tuple)) or hasattr(value, "tolist"):
            items = list(value.tolist() if hasattr(value, "tolist") else value)
            if all(isinstance(v, bool) for v in items) and items:
                return cls.BOOL_ARRAY
            if all(isinstance(v, int) and not isinstance(v, bool) for v in items):
                return cls.INTEGER_ARRAY
            if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in items):
                return cls.DOUBLE_ARRAY
            if all(isinstance(v, str) for v in items):
                return cls.STRING_ARRAY
        raise TypeError(f"{type(value).__name__} value {value!r} is not a valid ROS parameter value")


class Parameter:
    """A named parameter value, shaped like ``rclpy.parameter.Parameter``.

    Args:
        name: parameter name (dots separate groups, ``arm.kp``).
        type_: a ``Parameter.Type``; inferred from ``value`` when omitted.
        value: the value.
    """

    Type = _Type

    def __init__(self, name: str, type_: _Type | None = None, value: Any = None) -> None:
        if type_ is not None and not isinstance(type_, _Type):
            # Allow Parameter(name, value) positional use as in recent rclpy.
            type_, value = None, type_
        inferred = _Type.from_parameter_value(value)
        if type_ is None:
            type_ = inferred
        elif type_ != inferred and (type_, inferred) not in (
            (_Type.DOUBLE_ARRAY, _Type.INTEGER_ARRAY), (_Type.DOUBLE, _Type.INTEGER)
        ):
            raise InvalidParameterTypeException(
                f"parameter '{name}': value {value!r} is {inferred.name}, not {type_.name}"
            )
        if type_ == _Type.DOUBLE and isinstance(value, int):
            value = float(value)
        if type_ == _Type.DOUBLE_ARRAY and value is not None:
            value = [float(v) for v in value]
        elif isinstance(value, tuple):
            value = list(value)
        self._name = name
        self._type = type_
        self._value = value

    @property
    def name(self) -> str:
        return self._name

    @property
    def type_(self) -> _Type:
        return self._type

    @property
    def value(self) -> Any:
        return self._value

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, Parameter)
            and (self._name, self._type, self._value) == (other._name, other._type, other._value)
        )

    def __repr__(self) -> str:
        return f"Parameter({self._name!r}, {self._type.name}, {self._value!r})"


@dataclass
class ParameterDescriptor:
    """What a parameter is (subset of ``rcl_interfaces/msg/ParameterDescriptor``)."""

    name: str = ""
    type: int = 0
    description: str = ""
    additional_constraints: str = ""
    read_only: bool = False
    dynamic_typing: bool = False


@dataclass
class SetParametersResult:
    """Outcome of setting one parameter (``rcl_interfaces/msg/SetParametersResult``)."""

    successful: bool = True
    reason: str = ""


ParameterCallback = Callable[[list[Parameter]], SetParametersResult]


@dataclass
class ParameterStore:
    """The parameters of one node: declared values, descriptors, pending overrides, callbacks."""

    node_name: str
    overrides: dict[str, Any] = field(default_factory=dict)
    allow_undeclared: bool = False
    values: dict[str, Parameter] = field(default_factory=dict)
    descriptors: dict[str, ParameterDescriptor] = field(default_factory=dict)
    callbacks: list[ParameterCallback] = field(default_factory=list)

    def declare(
        self,
        name: str,
        value: Any = None,
        descriptor: ParameterDescriptor | None = None,
        ignore_override: bool = False,
    ) -> Parameter:
        """Declare ``name`` with a default; an override (YAML, ``-p``) replaces the default."""
        if name in self.values:
            raise ParameterAlreadyDeclaredException(name, self.node_name)
        if isinstance(value, Parameter.Type):
            # declare_parameter(name, Parameter.Type.X) declares a typed parameter without value.
            value = None
        descriptor = descriptor or ParameterDescriptor()
        descriptor.name = name
        if not ignore_override and name in self.overrides:
            value = self.overrides[name]
        param = Parameter(name, value=value)
        self._check(param, descriptor, declaring=True)
        descriptor.type = int(param.type_) if not descriptor.type else descriptor.type
        self.values[name] = param
        self.descriptors[name] = descriptor
        return param

    def get(self, name: str) -> Parameter:
        """The declared parameter ``name``."""
        try:
            return self.values[name]
        except KeyError:
            if self.allow_undeclared:
                return Parameter(name, value=None)
            raise ParameterNotDeclaredException(name, self.node_name) from None

    def set(self, parameters: Sequence[Parameter]) -> list[SetParametersResult]:
        """Set parameters one by one; each result says whether it was accepted and why not."""
        results = []
        for param in parameters:
            try:
                if param.name not in self.values:
                    if not self.allow_undeclared:
                        raise ParameterNotDeclaredException(param.name, self.node_name)
                    self.descriptors[param.name] = ParameterDescriptor(name=param.name, dynamic_typing=True)
                self._check(param, self.descriptors[param.name], declaring=False)
                for cb in self.callbacks:
                    res = cb([param])
                    if not res.successful:
                        raise InvalidParameterValueException(
                            f"parameter '{param.name}' rejected by a callback: {res.reason}"
                        )
            except (InvalidParameterTypeException, InvalidParameterValueException,
                    ParameterNotDeclaredException) as exc:
                results.append(SetParametersResult(False, str(exc)))
                continue
            self.values[param.name] = param
            results.append(SetParametersResult(True, ""))
        return results

    def _check(self, param: Parameter, descriptor: ParameterDescriptor, *, declaring: bool) -> None:
        if declaring:
            return
        if descriptor.read_only:
            raise InvalidParameterValueException(f"parameter '{param.name}' is read-only")
        old = self.values.get(param.name)
        if (
            old is not None
            and not descriptor.dynamic_typing
            and old.type_ != Parameter.Type.NOT_SET
            and param.type_ != old.type_
        ):
            raise InvalidParameterTypeException(
                f"parameter '{param.name}' is {old.type_.name}; cannot set it to {param.type_.name} "
                f"value {param.value!r} (declare it with ParameterDescriptor(dynamic_typing=True) to allow)"
            )


def _flatten(prefix: str, tree: dict[str, Any], out: dict[str, Any]) -> None:
    for key, value in tree.items():
        name = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, dict):
            _flatten(name, value, out)
        else:
            out[name] = value


def _node_pattern(key: str) -> re.Pattern[str]:
    key = key if key.startswith("/") else "/" + key
    out = []
    i = 0
    while i < len(key):
        if key.startswith("/**", i):
            out.append("(/[^/]+)*")
            i += 3
        elif key[i] == "*":
            out.append("[^/]*")
            i += 1
        else:
            out.append(re.escape(key[i]))
            i += 1
    return re.compile("".join(out))


def parameters_from_yaml(data: dict[str, Any] | str | Path, node_fqn: str) -> dict[str, Any]:
    """The parameter values a ROS 2 parameter YAML gives the node ``node_fqn`` (``/ns/name``).

    Entries apply in file order, so a node-specific section after ``/**`` overrides it.

    Raises:
        ValueError: the YAML does not have the ``<node>: ros__parameters:`` layout.
    """
    if isinstance(data, (str, Path)):
        data = load_parameter_file(data)
    values: dict[str, Any] = {}
    for node_key, section in data.items():
        if not isinstance(section, dict) or "ros__parameters" not in section:
            raise ValueError(
                f"parameter YAML entry '{node_key}' has no 'ros__parameters' key; expected "
                "'<node name>: {ros__parameters: {...}}'"
            )
        if _node_pattern(str(node_key)).fullmatch(node_fqn):
            _flatten("", section["ros__parameters"] or {}, values)
    return values


def load_parameter_file(path: str | Path) -> dict[str, Any]:
    """Read a ROS 2 parameter YAML file.

    Raises:
        FileNotFoundError: the file does not exist.
        ValueError: the file is not a YAML mapping.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"parameter file '{path}' not found")
    data = yaml.safe_load(path.read_text())
    if not isinstance(data, dict):
        raise ValueError(f"parameter file '{path}' must contain a mapping of node names")
    return data


def parameter_list(values: dict[str, Any]) -> list[Parameter]:
    """``Parameter`` objects for a name -> value mapping."""
    return [Parameter(k, value=v) for k, v in values.items()]


def merge_overrides(*sources: Iterable[Parameter] | dict[str, Any] | None) -> dict[str, Any]:
    """Merge override sources; later sources win."""
    merged: dict[str, Any] = {}
    for src in sources:
        if not src:
            continue
        if isinstance(src, dict):
            merged.update(src)
        else:
            merged.update({p.name: p.value for p in src})
    return merged
