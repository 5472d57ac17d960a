"""Docs cannot drift: every runnable code block of README.md and docs/*.md runs.

Each page runs in an empty temporary directory, in document order: ``{code-block}`` files with a
path caption are written, ``python`` snippets run each in a fresh Python process (the installed
uniros, the suite's private Zenoh router and ROS domain from tests/conftest.py), ``bash`` blocks
marked ``run`` run with the venv's programs first on ``PATH``. Markers (HTML comments above a
block, see ``docs_snippets.py``) skip a block that cannot run here, shrink a training run, or mark
it slow; blocks marked slow run in a second, slow test after the page's files and commands.

No network here: a page that works through a vendor's description package (docs/add_your_arm.md:
ROBOTIS' OpenManipulator-X) runs against the suite's stand-in of it, written from the same published
kinematics (``tests/robots/arm_add_data``, on ``AMENT_PREFIX_PATH`` as a sourced workspace puts it;
the page's ``replace`` marker names the stand-in's URI).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from docs_snippets import REPO, Block, all_blocks, pages, parse

# Python blocks that cannot run in this test environment, per page. Every opt-out is visible in the
# page's source (a "docs-test: skip <reason>" comment) and counted here; keep them few.
EXPECTED_SKIPS = {
    "docs/concepts.md": 1,      # sim_mode="existing": a uniros-sim started beforehand
    "docs/vector_envs.md": 2,   # nodes on other hosts; Ray RLlib (tested by tests/rllib in .venv-rllib)
    "docs/datasets.md": 1,      # LeRobot's reader (tested by tests/lerobot in .venv-lerobot)
    "docs/lerobot.md": 1,       # LeRobot's make_env (tested by tests/lerobot in .venv-lerobot)
}
MAX_SKIPS = 6
TIMEOUT = 180.0
VENV_BIN = Path(sys.executable).parent
DESCRIPTION_STAND_INS = REPO / "tests" / "robots" / "arm_add_data" / "install"


def _page_ids() -> list[str]:
    return [str(p.relative_to(REPO)) for p in pages()]


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PATH"] = f"{VENV_BIN}{os.pathsep}{env.get('PATH', '')}"
    env.setdefault("MUJOCO_GL", "egl")
    env["MPLBACKEND"] = "Agg"
    env.pop("PYTHONPATH", None)
    prefixes = (str(DESCRIPTION_STAND_INS), env.get("AMENT_PREFIX_PATH"))
    env["AMENT_PREFIX_PATH"] = os.pathsep.join(p for p in prefixes if p)
    return env


def _run(argv: list[str], cwd: Path, block: Block) -> None:
    try:
        proc = subprocess.run(argv, cwd=cwd, env=_env(), capture_output=True, text=True, timeout=TIMEOUT)
    except subprocess.TimeoutExpired as exc:  # subprocess.run kills the child on timeout
        pytest.fail(f"{block.where}: did not finish within {TIMEOUT:.0f} s\n{(exc.stderr or '')[-3000:]}")
    if proc.returncode != 0:
        pytest.fail(f"{block.where}: exited with {proc.returncode}\n--- code ---\n{block.runnable_code()}"
                    f"--- stdout ---\n{proc.stdout[-3000:]}\n--- stderr ---\n{proc.stderr[-5000:]}")


def _runnable(block: Block) -> bool:
    if block.is_file or block.skip_reason is not None:
        return False
    if block.lang == "python":
        return True
    return block.lang == "bash" and block.has("run")


def _run_page(page: str, tmp_path: Path, *, slow: bool) -> int:
    """Run the page's blocks in order; with ``slow``, only the slow ones (after files and commands)."""
    blocks = parse(REPO / page)
    ran = 0
    chain: list[Block] = []
    for i, block in enumerate(blocks):
        if block.is_file:
            target = tmp_path / block.caption
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_text(block.runnable_code())
            continue
        if not _runnable(block):
            continue
        chain = [*chain, block] if block.has("continue") else [block]
        follows = next((b for b in blocks[i + 1:] if _runnable(b)), None)
        if follows is not None and follows.has("continue"):
            continue  # run the chain with its last block
        is_slow = any(b.has("slow") for b in chain)
        setup = block.lang == "bash" and not is_slow
        if is_slow != slow and not (slow and setup):
            continue
        if block.lang == "python":
            script = tmp_path / f"snippet_{block.line}.py"
            script.write_text("\n".join(b.runnable_code() for b in chain))
            _run([sys.executable, str(script)], tmp_path, block)
        else:
            _run(["bash", "-e", "-o", "pipefail", "-c", block.runnable_code()], tmp_path, block)
        ran += 1
    return ran


# Pages whose fast blocks take over 10 s together on a quiet machine (each block makes an env, so a
# simulation node): marked slow as a whole, so that `-m "not slow"` stays quick (CI runs them all).
HEAVY_PAGES = {"docs/create_env.md", "docs/concepts.md", "docs/vector_envs.md", "docs/add_your_arm.md"}


@pytest.mark.parametrize("page", [pytest.param(p, marks=pytest.mark.slow) if p in HEAVY_PAGES else p
                                  for p in _page_ids()])
def test_page_code_runs(page, tmp_path):
    _run_page(page, tmp_path, slow=False)


@pytest.mark.slow
@pytest.mark.parametrize("page", [p for p in _page_ids() if any(b.has("slow") for b in parse(REPO / p))])
def test_page_slow_code_runs(page, tmp_path):
    assert _run_page(page, tmp_path, slow=True) > 0


def test_opt_outs_are_few_and_listed():
    skipped = [b for b in all_blocks() if b.lang == "python" and b.skip_reason is not None]
    found: dict[str, int] = {}
    for block in skipped:
        assert block.skip_reason != "(no reason given)", f"{block.where}: say why the block cannot run"
        found[block.page] = found.get(block.page, 0) + 1
    assert found == EXPECTED_SKIPS, (
        "python blocks skipped by the docs tests changed; make the block run, or count it in EXPECTED_SKIPS: "
        + "; ".join(f"{b.where}: {b.skip_reason}" for b in skipped)
    )
    assert sum(found.values()) <= MAX_SKIPS


def test_every_python_block_runs_or_says_why():
    for block in all_blocks():
        if block.lang == "python" and not block.is_file:
            assert _runnable(block) or block.skip_reason, block.where
        for marker in block.markers:
            if marker.startswith("replace"):
                block.runnable_code()  # raises when OLD no longer occurs in the block
