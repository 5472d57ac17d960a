"""An arm file's draft (``uniros arm add``): its values, a comment on each, and its YAML text.

:func:`~rl_environments.arm_inference.draft_arm` fills an :class:`ArmDraft` section by section with
what it inferred or guessed, with a comment on every value saying which and why, so the user reviews
one file instead of starting from a blank one; :func:`render_arm_file` writes it one key a line, its
comment beside it. Values are rounded as written (``_r``, ``_rl``), joint positions kept inside the
limits as written (``_rl_within``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["ArmDraft", "render_arm_file"]


@dataclass
class ArmDraft:
    """An arm file's values (the YAML's sections) with a comment per key, and its controllers file."""

    name: str
    sections: dict[str, Any] = field(default_factory=dict)
    comments: dict[str, str] = field(default_factory=dict)  # "section.key" or "section" -> comment
    header: list[str] = field(default_factory=list)
    controllers_yaml: str = ""
    settle_error: float = math.nan
    check: Any = None  # rl_environments.arm_check.ArmCheck of the drafted file (None: not checked)

    def note(self, key: str, text: str) -> None:
        self.comments[key] = text


def _r(value: float, digits: int = 4) -> float:
    out = round(float(value), digits)
    return 0.0 if out == 0 else out


def _rl(values: Sequence[float] | np.ndarray, digits: int = 4) -> list[float]:
    return [_r(v, digits) for v in values]


def _rl_within(values: Sequence[float] | np.ndarray, lower: Sequence[float] | np.ndarray,
               upper: Sequence[float] | np.ndarray) -> list[float]:
    """Joint positions rounded as written, kept inside the limits as written (``reach.min_joint_pos``'s
    5 digits): a pose at a limit must not round past it."""
    lo, hi = _rl(lower, 5), _rl(upper, 5)
    return [float(min(max(v, a), b)) for v, a, b in zip(_rl(values), lo, hi)]


def _flow(value: Any) -> str:
    import yaml

    if isinstance(value, float):
        return repr(value)
    if isinstance(value, str):
        return yaml.safe_dump(value, default_style=None).strip().removesuffix("...").strip() if value else "''"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_flow(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {_flow(v)}" for k, v in value.items()) + "}"
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def render_arm_file(draft: ArmDraft) -> str:
    """The YAML text of a draft: one key a line, its comment beside it."""
    lines = [f"# {h}" for h in draft.header]

    def comment(key: str) -> str:
        text = draft.comments.get(key)
        return f"  # {text}" if text else ""

    for section, value in draft.sections.items():
        if not isinstance(value, dict):
            lines.append(f"{section}: {_flow(value)}{comment(section)}")
            continue
        if section in draft.comments and section not in ("gripper",):
            lines.append(f"# {draft.comments[section]}")
        lines.append(f"{section}:{comment(section) if section == 'gripper' else ''}")
        for key, item in value.items():
            if isinstance(item, dict) and item:
                lines.append(f"  {key}:{comment(f'{section}.{key}')}")
                lines += [f"    {k}: {_flow(v)}" for k, v in item.items()]
            else:
                lines.append(f"  {key}: {_flow(item)}{comment(f'{section}.{key}')}")
    return "\n".join(lines) + "\n"
