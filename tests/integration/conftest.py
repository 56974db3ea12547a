"""Fixtures shared by the integration tests' modules."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from sim.campaign.trials import Namespaces
from sim.processes import RosCore
from tests.integration.three_machines import ROS


@pytest.fixture(scope="module")
def far_master(hosts: Namespaces) -> Iterator[RosCore]:
    """roscore on the ROS machine of the requesting module's three machines (its fixture `hosts`)."""
    core = RosCore(host=ROS, prefix=hosts.prefix(hosts.ros))
    yield core
    core.stop()
