"""YAML read within bounds: a file a user names (an arm file, a controllers file, a training config) may
be hostile or broken, and ``yaml.safe_load`` alone is not enough.

``safe_load`` refuses tags that run code, but it reads a 2 KB "billion laughs" (anchors whose aliases
refer to each other) into a structure that any later walk expands to billions of values, a file of
hundreds of megabytes whole, and a 50,000-deep nesting into a ``RecursionError`` traceback.
:func:`load_yaml_bounded` checks the size first, then scans the tokens (a linear pass that recurses
into nothing) for the nesting depth, and after composing counts the values the document expands to
(each node once, its aliases by reference), so each of those is one line naming the file, and only
then builds the Python objects (with libyaml's loader where PyYAML has it). PyYAML has no such limits of
its own, hence this module.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

__all__ = ["YamlBoundsError", "load_yaml_bounded", "read_yaml_bounded"]

MAX_BYTES = 1 << 20  # 1 MiB: an arm file or a controllers file is a few kilobytes
MAX_DEPTH = 64  # nested mappings and lists
MAX_VALUES = 50_000  # scalars, mappings and lists the document expands to, aliases expanded

_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)  # libyaml's: 20x faster to scan, 5x to compose
_OPEN = (yaml.BlockMappingStartToken, yaml.BlockSequenceStartToken, yaml.FlowMappingStartToken,
         yaml.FlowSequenceStartToken)
_CLOSE = (yaml.BlockEndToken, yaml.FlowMappingEndToken, yaml.FlowSequenceEndToken)


class YamlBoundsError(ValueError):
    """A YAML text that is not valid YAML, or too large, too deep or too many values once expanded."""


def read_yaml_bounded(path: str | Path, *, max_bytes: int = MAX_BYTES, max_depth: int = MAX_DEPTH,
                      max_values: int = MAX_VALUES) -> Any:
    """:func:`load_yaml_bounded` of a file's text; a file larger than ``max_bytes`` is not read whole.

    Raises:
        OSError: the file cannot be read.
        YamlBoundsError: as :func:`load_yaml_bounded`.
    """
    path = Path(path)
    with path.open("rb") as f:
        raw = f.read(max_bytes + 1)
    if len(raw) > max_bytes:
        raise YamlBoundsError(f"larger than {max_bytes:,} bytes (not read further)")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise YamlBoundsError(f"not UTF-8 text (byte {exc.start})") from None
    return load_yaml_bounded(text, max_bytes=max_bytes, max_depth=max_depth, max_values=max_values)


def load_yaml_bounded(text: str, *, max_bytes: int = MAX_BYTES, max_depth: int = MAX_DEPTH,
                      max_values: int = MAX_VALUES) -> Any:
    """``yaml.safe_load(text)`` within bounds (see the module docstring).

    Raises:
        YamlBoundsError: not valid YAML (its first line), larger than ``max_bytes``, nested deeper than
            ``max_depth``, or expanding to more than ``max_values`` values (aliases counted each time).
    """
    if len(text) > max_bytes:
        raise YamlBoundsError(f"larger than {max_bytes:,} bytes")
    try:
        depth = scalars = 0
        for token in yaml.scan(text, Loader=_LOADER):
            if isinstance(token, _OPEN):
                depth += 1
                if depth > max_depth:
                    raise YamlBoundsError(f"nested deeper than {max_depth} levels")
            elif isinstance(token, _CLOSE):
                depth -= 1
            elif isinstance(token, yaml.ScalarToken):
                scalars += 1
                if scalars > max_values:
                    raise YamlBoundsError(f"holds more than {max_values:,} values")
        loader = _LOADER(text)
        try:
            node = loader.get_single_node()
            if node is None:
                return None
            _count_values(node, max_values)
            return loader.construct_document(node)
        finally:
            loader.dispose()
    except yaml.YAMLError as exc:
        raise YamlBoundsError(f"not valid YAML: {str(exc).strip().splitlines()[0]}") from None


def _count_values(root: yaml.Node, most: int) -> None:
    """Refuse a document whose values, aliases expanded, number more than ``most``: each node's expanded
    size is computed once (a DAG walk, children before parents, no recursion)."""
    size: dict[int, int] = {}
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    while stack:
        node, ready = stack.pop()
        if id(node) in size:
            continue
        children: list[yaml.Node] = []
        if isinstance(node, yaml.SequenceNode):
            children = list(node.value)
        elif isinstance(node, yaml.MappingNode):
            children = [part for pair in node.value for part in pair]
        if ready or not children:
            total = 1 + sum(size[id(c)] for c in children)
            if total > most:
                raise YamlBoundsError(f"expands to more than {most:,} values (aliases of anchors count each time)")
            size[id(node)] = total
            continue
        stack.append((node, True))
        stack.extend((c, False) for c in children if id(c) not in size)
