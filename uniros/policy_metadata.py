"""What an exported policy says about itself: the JSON ``uniros export`` writes into the ONNX model's
``metadata_props`` (key :data:`METADATA_KEY`), and its checks.

``uniros export`` writes it (:mod:`uniros.policy_export`, with torch); ``uniros deploy`` reads it back on a
robot's machine (:mod:`uniros.onnx_policy`, onnxruntime only), so this module imports neither. An ONNX
file comes from anywhere: every field is checked (types, sizes, finite bounds) before it is used, and a
problem is one :class:`PolicyFileError` line naming the field.

The graph maps the env's raw observation to the env's action. A plain env's observation is one input,
``obs``; a dict observation (goal envs) is one input per key, named by the key, in the order of the
observation space's keys (SB3's ``CombinedExtractor`` concatenates them in that order inside the graph).
Every input has a leading batch dimension, and so has the one output, ``action``.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from dataclasses import asdict, dataclass, field
from typing import Any

#: The key of the uniros record in the ONNX model's ``metadata_props``.
METADATA_KEY = "uniros"
#: The record's format; a reader refuses another.
FORMAT = "uniros-policy/1"
#: Name of the input of a plain (non-dict) observation, and of the graph's output.
OBS_INPUT = "obs"
ACTION_OUTPUT = "action"
#: Input layouts: ``single`` (one ``obs`` input) or ``keys`` (a dict observation, one input per key).
LAYOUTS = ("single", "keys")
_DTYPES = ("float32", "float64")
_MAX_JSON = 1 << 20  # characters: a record is a few KB
_MAX_ELEMENTS = 1 << 16  # elements of one input or of the action
_MAX_INPUTS = 64


class PolicyFileError(ValueError):
    """An exported policy file is missing, not ONNX, without the uniros record, or its record is wrong."""


@dataclass(frozen=True)
class PolicyInput:
    """One input of the graph: ``name`` (``obs`` or a dict key), the shape of one observation, its dtype."""

    name: str
    shape: tuple[int, ...]
    dtype: str = "float32"


@dataclass(frozen=True)
class PolicyMetadata:
    """The uniros record of an exported policy.

    Attributes:
        env_id: the ID the policy was trained on (as ``run.json`` has it).
        arm_file: the arm file that registers ``env_id``, as ``run.json`` has it (relative: to the run's folder).
        env_kwargs: the env kwargs of the run (``run.json``).
        algorithm: ``sac``, ``td3``, ``ddpg``, ``tqc``, ``ppo``, ...
        layout: ``single`` or ``keys`` (see the module's docstring).
        inputs: the graph's inputs, in order.
        action_low, action_high: the action space's bounds (the graph's output lies within them).
        normalized: observation normalisation (VecNormalize) is inside the graph; ``normalized_keys``: which
            keys of a dict observation it covers; ``clip_obs``, ``epsilon``: its constants.
        control_period: seconds per env step on the Real twin, when known.
        uniros_version, exporter, opset, source_model, source_sha256: where the file came from.
    """

    env_id: str
    algorithm: str
    layout: str
    inputs: tuple[PolicyInput, ...]
    action_low: tuple[float, ...]
    action_high: tuple[float, ...]
    arm_file: str | None = None
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    normalized: bool = False
    normalized_keys: tuple[str, ...] = ()
    clip_obs: float | None = None
    epsilon: float | None = None
    control_period: float | None = None
    uniros_version: str = ""
    exporter: str = ""
    opset: int = 0
    source_model: str = ""
    source_sha256: str = ""

    @property
    def keys(self) -> tuple[str, ...] | None:
        """The dict observation's keys, in input order; ``None`` for a plain observation."""
        return tuple(i.name for i in self.inputs) if self.layout == "keys" else None

    @property
    def action_shape(self) -> tuple[int, ...]:
        return (len(self.action_low),)

    def to_json(self) -> str:
        data = asdict(self)
        data["format"] = FORMAT
        return json.dumps(data, sort_keys=True)

    @classmethod
    def from_json(cls, text: str, where: str) -> PolicyMetadata:
        """Parse and check a record; ``where`` names the file in messages.

        Raises:
            PolicyFileError: not JSON, another format, or a field of the wrong type or size.
        """
        if len(text) > _MAX_JSON:
            raise PolicyFileError(f"{where}: the uniros metadata is {len(text):,} characters (at most {_MAX_JSON:,})")
        try:
            data = json.loads(text)
        except ValueError as exc:
            raise PolicyFileError(f"{where}: the uniros metadata is not JSON ({exc})") from None
        if not isinstance(data, dict):
            raise PolicyFileError(f"{where}: the uniros metadata is not a JSON object")
        if data.get("format") != FORMAT:
            raise PolicyFileError(f"{where}: uniros metadata of format {str(data.get('format'))[:40]!r}, this uniros "
                                  f"reads {FORMAT!r} (export the policy again with this version)")
        check = _Checker(where, data)
        layout = check.choice("layout", LAYOUTS)
        raw_inputs = check.typed("inputs", list)
        if not 1 <= len(raw_inputs) <= _MAX_INPUTS or (layout == "single" and len(raw_inputs) != 1):
            raise PolicyFileError(f"{where}: metadata 'inputs' holds {len(raw_inputs)} inputs")
        inputs = tuple(_input(item, where) for item in raw_inputs)
        if len({i.name for i in inputs}) != len(inputs):
            raise PolicyFileError(f"{where}: metadata 'inputs' names an input twice")
        low, high = check.floats("action_low"), check.floats("action_high")
        if not 1 <= len(low) <= _MAX_ELEMENTS or len(low) != len(high) or any(lo > hi for lo, hi in zip(low, high)):
            raise PolicyFileError(f"{where}: metadata action bounds are not {len(low)} pairs with low <= high")
        period = data.get("control_period")
        if period is not None and not (_finite_number(period) and 0 < period <= 60):
            raise PolicyFileError(f"{where}: metadata 'control_period' {str(period)[:40]} is not in (0, 60] s")
        kwargs = data.get("env_kwargs") or {}
        if not isinstance(kwargs, dict) or not all(isinstance(k, str) for k in kwargs):
            raise PolicyFileError(f"{where}: metadata 'env_kwargs' is not a mapping of names")
        arm_file = data.get("arm_file")
        if arm_file is not None and not (isinstance(arm_file, str) and 0 < len(arm_file) <= 4096):
            raise PolicyFileError(f"{where}: metadata 'arm_file' is not a path")
        normalized_keys = tuple(check.strings("normalized_keys"))
        return cls(
            env_id=check.text("env_id"), algorithm=check.text("algorithm"), layout=layout, inputs=inputs,
            action_low=tuple(low), action_high=tuple(high), arm_file=arm_file, env_kwargs=dict(kwargs),
            normalized=bool(data.get("normalized", False)), normalized_keys=normalized_keys,
            clip_obs=check.optional_number("clip_obs"), epsilon=check.optional_number("epsilon"),
            control_period=None if period is None else float(period),
            uniros_version=str(data.get("uniros_version", ""))[:64], exporter=str(data.get("exporter", ""))[:64],
            opset=int(data.get("opset", 0)) if isinstance(data.get("opset", 0), int) else 0,
            source_model=str(data.get("source_model", ""))[:4096],
            source_sha256=str(data.get("source_sha256", ""))[:64],
        )


def file_sha256(path: str | os.PathLike[str]) -> str:
    """The SHA-256 of a file (the record names the model a policy was exported from by it)."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _finite_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _input(item: Any, where: str) -> PolicyInput:
    if not isinstance(item, dict):
        raise PolicyFileError(f"{where}: a metadata input is not an object")
    name, shape, dtype = item.get("name"), item.get("shape"), item.get("dtype", "float32")
    if not isinstance(name, str) or not 0 < len(name) <= 128:
        raise PolicyFileError(f"{where}: a metadata input has no name")
    if (not isinstance(shape, list) or not 1 <= len(shape) <= 4
            or not all(isinstance(n, int) and not isinstance(n, bool) and n > 0 for n in shape)
            or math.prod(shape) > _MAX_ELEMENTS):
        raise PolicyFileError(f"{where}: metadata input {name!r} has the shape {str(shape)[:60]}")
    if dtype not in _DTYPES:
        raise PolicyFileError(f"{where}: metadata input {name!r} has the dtype {str(dtype)[:20]!r}, not one of "
                              f"{_DTYPES}")
    return PolicyInput(name, tuple(shape), dtype)


class _Checker:
    """Typed reads of the record's fields, each a one-line :class:`PolicyFileError` when wrong."""

    def __init__(self, where: str, data: dict[str, Any]) -> None:
        self.where, self.data = where, data

    def _fail(self, key: str, what: str) -> PolicyFileError:
        return PolicyFileError(f"{self.where}: metadata {key!r} is {what}")

    def typed(self, key: str, kind: type) -> Any:
        value = self.data.get(key)
        if not isinstance(value, kind):
            raise self._fail(key, f"not a {kind.__name__}")
        return value

    def text(self, key: str) -> str:
        value = self.typed(key, str)
        if not 0 < len(value) <= 256:
            raise self._fail(key, "empty or too long")
        return str(value)

    def choice(self, key: str, choices: tuple[str, ...]) -> str:
        value = self.data.get(key)
        if value not in choices:
            raise self._fail(key, f"not one of {choices}")
        return str(value)

    def floats(self, key: str) -> list[float]:
        values = self.typed(key, list)
        if len(values) > _MAX_ELEMENTS or not all(_finite_number(v) for v in values):
            raise self._fail(key, "not a list of finite numbers")
        return [float(v) for v in values]

    def strings(self, key: str) -> list[str]:
        values = self.data.get(key) or []
        if not isinstance(values, list) or len(values) > _MAX_INPUTS or not all(isinstance(v, str) for v in values):
            raise self._fail(key, "not a list of names")
        return list(values)

    def optional_number(self, key: str) -> float | None:
        value = self.data.get(key)
        if value is None:
            return None
        if not _finite_number(value):
            raise self._fail(key, "not a finite number")
        return float(value)


__all__ = ["ACTION_OUTPUT", "FORMAT", "LAYOUTS", "METADATA_KEY", "OBS_INPUT", "PolicyFileError", "PolicyInput",
           "PolicyMetadata", "file_sha256"]
