"""Code blocks of the documentation pages, and the markers that say how the tests treat them.

A fenced block is one of:

* a **file**: a ``{code-block}`` with a ``:caption:`` that is a relative path (``my_arm/__init__.py``);
  the tests write it, relative to the page's working directory, where it appears;
* a **snippet**: a ```` ```python ```` block (or a ``{code-block} python`` without a caption); run,
  in its own Python process, unless marked ``skip``;
* a **command**: a ```` ```bash ```` block; run with bash only when marked ``run``.

Markers are HTML comments on the lines right above the fence (invisible in the rendered page, visible
in its source)::

    <!-- docs-test: skip <why it cannot run here> -->
    <!-- docs-test: run -->                   (a bash block: run it)
    <!-- docs-test: slow -->                  (also: "run slow")
    <!-- docs-test: replace OLD => NEW -->    (shrink a training run; OLD must occur in the block)
    <!-- docs-test: continue -->              (run after the page's previous snippet, in one process)
    <!-- docs-test: distro rolling -->        (ros2 commands written for another ROS 2 distribution)
"""

from __future__ import annotations

import re
import shlex
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
DOCS = REPO / "docs"
GENERATED = {"env_ids", "_build", "_static", "_ext", "scripts"}

_MARKER = re.compile(r"^<!--\s*docs-test:\s*(.*?)\s*-->\s*$")
_FENCE = re.compile(r"^(`{3,})(.*)$")
_WORDS = {"skip", "run", "slow", "replace", "continue", "distro"}


@dataclass
class Block:
    """One fenced code block of a page."""

    page: str  # path relative to the repository
    line: int  # 1-based line of the opening fence
    lang: str
    code: str
    caption: str | None = None
    markers: list[str] = field(default_factory=list)

    @property
    def where(self) -> str:
        return f"{self.page}:{self.line}"

    @property
    def is_file(self) -> bool:
        if self.caption is None:
            return False
        return "/" in self.caption or re.search(r"\.(py|ya?ml|xacro|urdf|xml|txt|cfg|toml)$", self.caption) is not None

    @property
    def skip_reason(self) -> str | None:
        for m in self.markers:
            if m.split()[0] == "skip":
                return m[4:].strip() or "(no reason given)"
        return None

    def has(self, word: str) -> bool:
        return any(word in m.split() for m in self.markers if not m.startswith(("skip", "replace")))

    @property
    def distro(self) -> str:
        """The ROS 2 distribution of the block's ``ros2`` commands (``distro`` marker; Jazzy by default)."""
        for m in self.markers:
            if m.startswith("distro "):
                return m.split()[1]
        return "jazzy"

    def runnable_code(self) -> str:
        """The code with its ``replace`` markers applied (each OLD must occur)."""
        code = self.code
        for m in self.markers:
            if m.startswith("replace "):
                old, sep, new = m[len("replace "):].partition(" => ")
                if not sep or old not in code:
                    raise ValueError(f"{self.where}: marker 'replace {old} => ...' does not match the block")
                code = code.replace(old, new)
        return code


def pages() -> list[Path]:
    """README.md and the hand-written pages under docs/ (not the generated ones)."""
    found = [REPO / "README.md"]
    for path in sorted(DOCS.rglob("*.md")):
        if not GENERATED & set(path.relative_to(DOCS).parts):
            found.append(path)
    return found


def parse(path: Path) -> list[Block]:
    """Every fenced block of a Markdown page, with its markers and caption."""
    lines = path.read_text().splitlines()
    page = str(path.relative_to(REPO))
    blocks: list[Block] = []
    i = 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        fence, info = m.group(1), m.group(2).strip()
        start = i
        j = i + 1
        while j < len(lines) and not (lines[j].startswith(fence) and lines[j].strip() == fence):
            j += 1
        body = lines[i + 1:j]
        caption = None
        directive = re.match(r"^\{(code-block|code)\}\s*(\S*)", info)
        if directive:
            lang = directive.group(2)
            while body and body[0].startswith(":"):
                key, _, value = body.pop(0)[1:].partition(":")
                if key.strip() == "caption":
                    caption = value.strip()
            if body and not body[0].strip():
                body.pop(0)
        elif info.startswith("{"):
            lang = info  # another directive (toctree, include, eval-rst)
        else:
            lang = info.split()[0] if info else ""
        markers = []
        k = start - 1
        while k >= 0 and (mm := _MARKER.match(lines[k].strip())):
            markers.insert(0, mm.group(1))
            k -= 1
        for marker in markers:
            if marker.split()[0] not in _WORDS:
                raise ValueError(f"{page}:{start + 1}: unknown docs-test marker {marker!r}")
        blocks.append(Block(page, start + 1, lang, "\n".join(body) + "\n", caption, markers))
        i = j + 1
    return blocks


def all_blocks() -> list[Block]:
    return [b for p in pages() for b in parse(p)]


def shell_lines(block: Block) -> list[list[str]]:
    """The block's shell lines as shell words (``\\`` continuations and quotes spanning lines joined,
    comments dropped); unbalanced quotes are an error naming the block."""
    found, pending = [], ""
    for line in block.code.replace("\\\n", " ").splitlines():
        pending = f"{pending}\n{line}" if pending else line
        try:
            words = shlex.split(pending, comments=True)
        except ValueError:  # a quote spans lines: read on
            continue
        pending = ""
        if words:
            found.append(words)
    assert not pending, f"{block.where}: unbalanced quotes"
    return found
