"""The generated env pages (docs/_ext/env_pages.py): one per registered ID, spaces from the code."""

from __future__ import annotations

import importlib.util
import sys

import pytest
from docs_snippets import DOCS

import rl_environments


@pytest.fixture(scope="module")
def env_pages():
    spec = importlib.util.spec_from_file_location("uniros_docs_env_pages", DOCS / "_ext" / "env_pages.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop(spec.name, None)


@pytest.fixture(scope="module")
def infos(env_pages):
    return env_pages.collect()


def test_every_registered_id_gets_a_page(env_pages, infos, tmp_path):
    ids = [info.env_id for info in infos]
    assert ids == [*rl_environments.ENV_IDS, *rl_environments.REAL_ENV_IDS]
    written = env_pages.write_pages(tmp_path, infos)
    assert {p.name for p in written} == {f"{i}.md" for i in ids} | {"_summary.md"}
    assert env_pages.write_pages(tmp_path, infos) == []  # unchanged pages are not rewritten
    summary = (tmp_path / "env_ids" / "_summary.md").read_text()
    for env_id in ids:
        assert f"env_ids/{env_id}.md" in summary and f"env_ids/{env_id}\n" in summary


def test_pages_say_what_the_code_does(env_pages, infos, tmp_path):
    import uniros

    by_id = {info.env_id: info for info in infos}
    known = set(by_id)
    env = uniros.make("RX200ReacherSim-v0")
    try:
        assert by_id["RX200ReacherSim-v0"].observation_space == env.observation_space
        assert by_id["RX200ReacherSim-v0"].action_space == env.action_space
    finally:
        env.close()
    page = env_pages.render_page(by_id["RX200ReacherSim-v0"], known, tmp_path)
    assert "`Box` of shape `(22,)`" in page and "| episode length | 100 steps" in page
    assert "| `reward_type` | `'dense'` |" in page and "\n## Rewards" not in page and "\n### Rewards" in page
    assert "From the docstring of {py:mod}`rl_environments.reach_task`" in page and "manipulation_task`" not in page
    assert "[`RX200ReacherReal-v0`](RX200ReacherReal-v0.md)" in page
    push = env_pages.render_page(by_id["RX200PushGoalSim-v0"], known, tmp_path)
    assert "50 steps" in push and "rl_environments.manipulation_task" in push and "### Rewards" in push
    real = by_id["ABBIRB120ReacherGoalRealEnv-v0"]
    assert real.observation_space == by_id["ABBIRB120ReacherGoalEnv-v0"].observation_space
    assert "Equal to [`ABBIRB120ReacherGoalEnv-v0`]" in env_pages.render_page(real, known, tmp_path)


def test_picture_shown_when_it_exists(env_pages, infos, tmp_path):
    info = next(i for i in infos if i.env_id == "RX200ReacherGoalReal-v0")
    known = {i.env_id for i in infos}
    assert "![" not in env_pages.render_page(info, known, tmp_path)
    (tmp_path / "_static" / "envs").mkdir(parents=True)
    (tmp_path / "_static" / "envs" / "RX200ReacherGoalSim-v0.png").write_bytes(b"\x89PNG")
    page = env_pages.render_page(info, known, tmp_path)
    assert "![RX200ReacherGoalSim-v0 (the simulated twin)](../_static/envs/RX200ReacherGoalSim-v0.png)" in page


def test_every_simulated_id_has_its_picture():
    missing = [i for i in rl_environments.ENV_IDS if not (DOCS / "_static" / "envs" / f"{i}.png").is_file()]
    assert not missing, f"render them: docs/scripts/render_env_images.py --ids {' '.join(missing)}"


def test_an_arms_page_has_its_class_and_its_task(env_pages, infos):
    by_id = {info.env_id: info for info in infos}
    known = set(by_id)
    page = env_pages.render_page(by_id["UR5ePnPGoalSim-v0"], known, DOCS)
    assert page.index("the goal-conditioned UR5e pick-and-place") < page.index("From the docstring of")  # class first
    assert "rl_environments.manipulation_task" in page and "### Rewards" in page
    assert "rl_environments.reach_task`" not in page  # only the modules this ID refers to
    assert "![UR5ePnPGoalSim-v0](../_static/envs/UR5ePnPGoalSim-v0.png)" in page
    real = env_pages.render_page(by_id["UR5ePnPGoalReal-v0"], known, DOCS)
    assert "![UR5ePnPGoalSim-v0 (the simulated twin)]" in real and "PoseStamped" in real
