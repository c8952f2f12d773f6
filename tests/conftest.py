"""Shared fixtures. GL fixtures live further down (marker ``gl``); window tests use ``window``."""
from __future__ import annotations

import pytest

from framework.world import World


@pytest.fixture
def world():
    """A fresh World (dt = 1/60 s) with no systems, closed after the test."""
    w = World()
    yield w
    w.close()
