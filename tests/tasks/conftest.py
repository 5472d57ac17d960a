"""Fixtures of the task tests: envs made through ``uniros.make`` and closed after each test."""

from __future__ import annotations

import pytest

import uniros


@pytest.fixture
def make():
    envs = []

    def _make(env_id, **kwargs):
        env = uniros.make(env_id, **kwargs)
        envs.append(env)
        return env

    yield _make
    for env in envs:
        env.close()
