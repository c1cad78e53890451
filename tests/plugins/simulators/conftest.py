"""Fixtures shared by the simulator backends' tests."""

from __future__ import annotations

import pytest
from coadapt_plugins.robots.kuafu.robot import Kuafu


@pytest.fixture(scope="module")
def kuafu() -> Kuafu:
    return Kuafu()
