"""Shared fixtures: small, fast probe settings for the default (non-slow) suite."""

from __future__ import annotations

import pytest

import plate_env as pe


@pytest.fixture(scope="session")
def tilelink():
    return pe.make_physics("tilelink")


@pytest.fixture(scope="session")
def cheese():
    return pe.preset("cheese")
