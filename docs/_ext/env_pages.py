"""Sphinx extension: one page per registered uniros env ID, written from the code at build time.

For every ID in ``rl_environments`` (simulated and Real), ``env_ids/<ID>.md`` gets the entry point,
the kind of env, the episode length, the task's keyword options (from the task class' signature),
the observation and action spaces (from an env built with ``uniros.make``: a composed simulation
node, about 0.1 s per ID; a Real env's spaces are its simulated twin's, which the tests compare),
the picture ``_static/envs/<ID>.png`` when it exists (a Real ID shows its simulated twin's), the
env class' docstring, and the env module's docstring (its description, rewards, success and episode
end) with those of the ``rl_environments`` modules either refers to by ``:mod:`` (an arm's IDs share
one module and the tasks' modules say what every arm's task is). ``env_ids/_summary.md`` is the
table the Environments page includes. Files are rewritten only when their text changes.

Nothing here is committed output: ``docs/.gitignore`` ignores ``env_ids/``.
"""

from __future__ import annotations

import importlib
import inspect
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

PAGES_DIR = "env_ids"
IMAGES_DIR = Path("_static") / "envs"
_ROLE = re.compile(r":(mod|class|func|meth|attr|data|obj|exc):`")
_MOD_REF = re.compile(r":mod:`~?(rl_environments[\w.]+)`")


@dataclass
class EnvInfo:
    """What a page says about one ID."""

    env_id: str
    entry_point: str
    real: bool
    goal: bool
    max_episode_steps: int | None
    twin: str | None
    observation_space: Any = None
    action_space: Any = None
    options: list[tuple[str, str]] = field(default_factory=list)
    docstrings: list[tuple[str, str]] = field(default_factory=list)  # (module, docstring)
    class_doc: str = ""


def collect(build_spaces: bool = True) -> list[EnvInfo]:
    """Every registered uniros ID, simulated first, with its spaces (``build_spaces``) and docs."""
    import gymnasium

    import rl_environments
    import uniros

    real_to_sim = {real: sim for sim, real in rl_environments.SIM_TO_REAL.items()}
    goal_ids = set(rl_environments.GOAL_ENV_IDS) | set(rl_environments.REAL_GOAL_ENV_IDS)
    infos: list[EnvInfo] = []
    spaces: dict[str, tuple[Any, Any]] = {}
    for env_id in (*rl_environments.ENV_IDS, *rl_environments.REAL_ENV_IDS):
        spec = gymnasium.spec(env_id)
        real = env_id in rl_environments.REAL_ENV_SPECS
        twin = real_to_sim.get(env_id) if real else rl_environments.SIM_TO_REAL.get(env_id)
        info = EnvInfo(env_id, str(spec.entry_point), real, env_id in goal_ids, spec.max_episode_steps, twin)
        module_name, _, class_name = info.entry_point.partition(":")
        module = importlib.import_module(module_name)
        cls = getattr(module, class_name)
        if "task" in spec.kwargs:  # an arm env: an arm and a task (rl_environments.arm_env)
            task = rl_environments.env_ids.task_class(spec.kwargs["task"])
            info.options = _arm_task_options(task, info.goal)
            info.class_doc = _arm_env_doc(env_id, class_name, spec.kwargs, task, real, twin)
            info.docstrings = _docstrings(importlib.import_module(task.__module__), info.class_doc)
        else:
            info.options = _task_options(cls)
            info.class_doc = inspect.cleandoc(vars(cls).get("__doc__") or "")
            info.docstrings = _docstrings(module, info.class_doc)
        if build_spaces and not real:
            env = uniros.make(env_id)
            try:
                spaces[env_id] = (env.observation_space, env.action_space)
            finally:
                env.close()
        if build_spaces and real and twin in spaces:
            spaces[env_id] = spaces[twin]
        info.observation_space, info.action_space = spaces.get(env_id, (None, None))
        infos.append(info)
    return infos


#: What each task does, for the pages of the arms' IDs.
_TASK_WORDS = {"reach": "reach", "push": "push", "pnp": "pick-and-place", "slide": "slide",
               "frobs_reach": "FRobs_RL reacher"}


def _arm_env_doc(env_id: str, class_name: str, kwargs: dict[str, Any], task: type, real: bool,
                 twin: str | None) -> str:
    """The first paragraph of an arm env's page: what it is made of and what it does."""
    arm, name = kwargs["arm"], kwargs["task"]
    first = (inspect.getdoc(task) or "").split("\n\n")[0].replace("\n", " ").replace(" (see the module docstring)", "")
    ref = f"the task: :class:`~{task.__module__}.{task.__name__}`; the arm: :class:`~rl_environments.arm.Arm`"
    made = f"``{class_name}(arm={arm!r}, task={name!r})``"
    what = ("the goal-conditioned " if "Goal" in class_name else "the ") + f"{arm} {_TASK_WORDS.get(name, name)}"
    if "Goal" in class_name:
        what += ", for HER"
    if not real:
        return f"``{env_id}``: {what}, {made} ({ref}). {first}"
    extra = (" The object's pose comes from a tracker (``geometry_msgs/PoseStamped``) and the gripper is "
             "commanded through its driver (:meth:`~rl_environments.arm.Arm.real_kwargs`)." if task.SCENE else "")
    return (f"``{env_id}``: ``{twin}``'s task on a real {arm}: {what}, {made} ({ref}; robot and loop knobs: "
            f":meth:`~rl_environments.arm.Arm.real_kwargs`).{extra} {first}")


def _arm_task_options(task: type, goal: bool) -> list[tuple[str, str]]:
    """An arm task's keyword options (its ``OPTIONS`` record), with the default of its kind of env."""
    import dataclasses

    out = []
    for f in dataclasses.fields(task.OPTIONS):
        default = f.default
        if f.name == "reward_type" and default is None:
            default = "sparse" if goal else "dense"
        out.append((f.name, repr(default)))
    return out


def _task_options(cls: type) -> list[tuple[str, str]]:
    """Keyword options of the first class in the MRO whose ``__init__`` names any (the task class)."""
    for klass in cls.__mro__:
        init = vars(klass).get("__init__")
        if init is None:
            continue
        params = [p for p in inspect.signature(init).parameters.values()
                  if p.name != "self" and p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL)]
        if params:
            return [(p.name, repr(p.default)) for p in params if p.default is not p.empty]
    return []


def _docstrings(module: Any, class_doc: str = "") -> list[tuple[str, str]]:
    """The module's docstring, then those of the ``rl_environments`` modules it or the env class'
    docstring refers to by ``:mod:``."""
    doc = inspect.getdoc(module) or ""
    out = [(module.__name__, doc)]
    for ref in dict.fromkeys(_MOD_REF.findall(class_doc) + _MOD_REF.findall(doc)):
        if ref != module.__name__:
            out.append((ref, inspect.getdoc(importlib.import_module(ref)) or ""))
    return out


# -- rendering --------------------------------------------------------------------------------------
def _fmt(x: float) -> str:
    return "inf" if np.isposinf(x) else "-inf" if np.isneginf(x) else f"{x:.4g}"


def space_summary(space: Any) -> str:
    """``Box(22)``, ``Dict(observation 18, achieved_goal 3, desired_goal 3)``, ..."""
    from gymnasium import spaces

    if space is None:
        return "see the twin"
    if isinstance(space, spaces.Dict):
        return "Dict(" + ", ".join(f"{k} {space_summary(v)[4:-1]}" for k, v in space.spaces.items()) + ")"
    if isinstance(space, spaces.Box):
        return f"Box({', '.join(map(str, space.shape))})"
    return repr(space)


def _space_section(title: str, space: Any) -> list[str]:
    from gymnasium import spaces

    lines = [f"### {title}", ""]
    if isinstance(space, spaces.Dict):
        lines += [f"`Dict` with keys {', '.join(f'`{k}`' for k in space.spaces)}:", ""]
        for key, sub in space.spaces.items():
            lines += _box_table(f"`{key}`", sub)
        return lines
    if isinstance(space, spaces.Box):
        return lines + _box_table("", space)
    return lines + [f"`{space!r}`", ""]


def _box_table(label: str, box: Any) -> list[str]:
    low, high = box.low.ravel(), box.high.ravel()
    head = f"{label}: " if label else ""
    lines = [f"{head}`Box` of shape `{box.shape}`, `{np.dtype(box.dtype).name}`", ""]
    if np.all(low == low[0]) and np.all(high == high[0]):
        return lines + [f"every entry in [{_fmt(low[0])}, {_fmt(high[0])}]", ""]
    lines += ["| index | low | high |", "|---:|---:|---:|"]
    lines += [f"| {i} | {_fmt(lo)} | {_fmt(hi)} |" for i, (lo, hi) in enumerate(zip(low, high))]
    return lines + [""]


def _markdown_docstring(doc: str, known_ids: set[str], this_id: str, demote: int) -> str:
    """A module docstring (Markdown headings, RST literals and roles) as MyST Markdown."""
    text = _ROLE.sub(lambda m: "{py:" + m.group(1) + "}`", doc)
    for env_id in known_ids - {this_id}:
        text = text.replace(f"``{env_id}``", f"[`{env_id}`]({env_id}.md)")
    if demote:
        text = re.sub(r"^(#+) ", lambda m: "#" * (len(m.group(1)) + demote) + " ", text, flags=re.M)
    return text.strip() + "\n"


def render_page(info: EnvInfo, known_ids: set[str], srcdir: Path) -> str:
    """The Markdown of ``env_ids/<ID>.md``."""
    module, _, cls = info.entry_point.partition(":")
    kind = "goal-conditioned (`GoalEnv`, dict observations, HER-ready)" if info.goal else "plain `gymnasium.Env`"
    runs = ("a real ros2_control robot, or a stand-in (see [Real robots](../real_robots.md))" if info.real
            else "the simulation node, composed in your process by default (runs anywhere)")
    lines = [f"# {info.env_id}", ""]
    image_id = info.env_id if (srcdir / IMAGES_DIR / f"{info.env_id}.png").is_file() else None
    if image_id is None and info.twin and (srcdir / IMAGES_DIR / f"{info.twin}.png").is_file():
        image_id = info.twin
    if image_id is not None:
        caption = "" if image_id == info.env_id else " (the simulated twin)"
        lines += [f"![{image_id}{caption}](../{IMAGES_DIR.as_posix()}/{image_id}.png)", ""]
    lines += [
        "| | |", "|---|---|",
        f"| make | `uniros.make(\"{info.env_id}\")` |",
        f"| kind | {kind} |",
        f"| runs on | {runs} |",
        f"| entry point | `{module}:{cls}` ({{py:class}}`API <{module}.{cls}>`) |",
        f"| episode length | {info.max_episode_steps} steps (`max_episode_steps`), then truncated |",
    ]
    if info.twin:
        label = "simulated twin" if info.real else "real twin"
        lines.append(f"| {label} | [`{info.twin}`]({info.twin}.md) |")
    lines += ["", "## Spaces", ""]
    if info.real:
        lines += [f"Equal to [`{info.twin}`]({info.twin}.md)'s (the Real env tests compare them), so a "
                  "model trained in simulation runs here unchanged.", ""]
    if info.observation_space is not None:
        lines += _space_section("Observation space", info.observation_space)
        lines += _space_section("Action space", info.action_space)
    lines += ["## Options", ""]
    if info.options:
        lines += ["Keyword arguments of `uniros.make` for this task (defaults shown):", "",
                  "| keyword | default |", "|---|---|"]
        lines += [f"| `{name}` | `{default}` |" for name, default in info.options]
        lines.append("")
    if info.real:
        lines += ["Plus the Real env knobs (namespace, controller names, loop rate, safety rules): "
                  "[Real robots](../real_robots.md).", ""]
    else:
        lines += ["Plus every base-env knob (`sim_mode`, `num_sim_steps`, `render_mode`, ...): "
                  "[Constructor knobs](../envs.md#constructor-knobs).", ""]
    for i, (mod, doc) in enumerate(info.docstrings):
        if not doc:
            continue
        if i == 0:
            lines += ["## Description", ""]
            if info.class_doc:
                lines += [_markdown_docstring(info.class_doc, known_ids, info.env_id, demote=0)]
            lines += [f"From the docstring of {{py:mod}}`{mod}`:", ""]
        else:
            lines += [f"### From {{py:mod}}`{mod}`", ""]
        lines.append(_markdown_docstring(doc, known_ids, info.env_id, demote=1 + (i > 0)))
    return "\n".join(lines)


def render_summary(infos: list[EnvInfo]) -> str:
    """The table of every ID and the hidden toctree of their pages (included by environments.md)."""
    lines = ["| ID | kind | runs on | observation | action | steps |", "|---|---|---|---|---|---|"]
    for info in infos:
        lines.append(
            f"| [`{info.env_id}`]({PAGES_DIR}/{info.env_id}.md) | {'goal' if info.goal else 'plain'} | "
            f"{'robot' if info.real else 'simulation'} | {space_summary(info.observation_space)} | "
            f"{space_summary(info.action_space)} | {info.max_episode_steps} |"
        )
    lines += ["", "```{toctree}", ":hidden:", ""]
    lines += [f"{PAGES_DIR}/{info.env_id}" for info in infos]
    return "\n".join(lines + ["```", ""])


def write_pages(srcdir: Path, infos: list[EnvInfo]) -> list[Path]:
    """Write ``env_ids/*.md`` (only files whose text changed; stale pages removed). Returns the written."""
    out = srcdir / PAGES_DIR
    out.mkdir(exist_ok=True)
    known = {info.env_id for info in infos}
    wanted = {out / f"{info.env_id}.md": render_page(info, known, srcdir) for info in infos}
    wanted[out / "_summary.md"] = render_summary(infos)
    written = []
    for path, text in wanted.items():
        if not path.is_file() or path.read_text() != text:
            path.write_text(text)
            written.append(path)
    for stale in set(out.glob("*.md")) - set(wanted):
        stale.unlink()
    return written


def _on_builder_inited(app: Any) -> None:
    from sphinx.util import logging

    logger = logging.getLogger(__name__)
    try:
        infos = collect()
    except Exception as exc:  # a broken env must fail the build (-W), with the reason
        logger.warning("env pages: building the registered envs failed: %s: %s", type(exc).__name__, exc)
        raise
    written = write_pages(Path(app.srcdir), infos)
    logger.info("env pages: %d IDs, %d page(s) rewritten", len(infos), len(written))


def setup(app: Any) -> dict[str, Any]:
    app.connect("builder-inited", _on_builder_inited)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
