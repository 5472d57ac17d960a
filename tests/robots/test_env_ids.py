"""The ID table (rl_environments.env_ids): one table the ID tuples are computed from, nothing rebound."""

from __future__ import annotations

import os

import pytest
import yaml

import rl_environments
from rl_environments.arm_registry import register_arm, unregister_arm

SHIPPED = rl_environments.shipped_arm_file("ur5e.yaml").parent  # type: ignore[union-attr] - a checkout's or an install's
TUPLES = ("ENV_IDS", "REAL_ENV_IDS", "GOAL_ENV_IDS", "REAL_GOAL_ENV_IDS", "MANIPULATION_ENV_IDS")


def test_the_id_tuples_are_read_from_one_table_and_follow_registration(tmp_path, monkeypatch):
    monkeypatch.setenv("UNIROS_ARMS", os.environ.get("UNIROS_ARMS", ""))
    assert not set(TUPLES) & set(vars(rl_environments)), "computed when read, never rebound"
    before = {name: getattr(rl_environments, name) for name in TUPLES}
    data = yaml.safe_load((SHIPPED / "ur5e.yaml").read_text())
    data["name"], data["robot_name"] = "TableArm", "tablearm"
    path = tmp_path / "table_arm.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    register_arm(path)
    try:
        assert "TableArmPushSim-v0" in rl_environments.ENV_IDS
        assert "TableArmPushReal-v0" in rl_environments.REAL_ENV_IDS
        assert "TableArmPnPGoalSim-v0" in rl_environments.GOAL_ENV_IDS
        assert "TableArmPnPGoalReal-v0" in rl_environments.REAL_GOAL_ENV_IDS
        assert "TableArmPushSim-v0" in rl_environments.MANIPULATION_ENV_IDS
        assert "TableArmReacherSim-v0" not in rl_environments.MANIPULATION_ENV_IDS
        assert rl_environments.EPISODE_STEPS["TableArmPnPReal-v0"] == 50
    finally:
        unregister_arm("TableArm")
    assert {name: getattr(rl_environments, name) for name in TUPLES} == before
    assert not [k for k in rl_environments.SIM_TO_REAL if k.startswith("TableArm")]
    with pytest.raises(AttributeError, match="no attribute 'NOT_A_TABLE'"):
        rl_environments.NOT_A_TABLE  # noqa: B018
