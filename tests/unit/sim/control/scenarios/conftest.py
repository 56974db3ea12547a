"""The bundled robots every scenario is built for."""

from __future__ import annotations

import pytest

from sim.robots import RobotSpec, load_robot


@pytest.fixture(scope="module", params=("panda", "igt"))
def robot(request: pytest.FixtureRequest) -> RobotSpec:
    return load_robot(request.param)
