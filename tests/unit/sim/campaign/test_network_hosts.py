"""The namespaces a run of network_hosts left behind (sim.campaign.trials): a run killed before its clean-up leaves
its namespaces, which must not stand in the way of the next run's."""

from __future__ import annotations

from sim.campaign.trials import stale_namespaces

# `ip netns list` as iproute2 prints it: a namespace with an id assigned says so
LISTED = """vrt_xm_4242_engine (id: 2)
vrt_xm_4242_bridge (id: 1)
vrt_xm_4242_ros (id: 0)
vrt_xm_77_ros
vrt_pl_4242_ros
vrt_xm_ros
vrt_xm_9_other
someone_elses
"""


def test_only_this_tags_namespaces_of_processes_that_are_gone_are_stale() -> None:
    gone = {4242}
    assert stale_namespaces("xm", LISTED, lambda pid: pid not in gone) == [
        "vrt_xm_4242_engine",
        "vrt_xm_4242_bridge",
        "vrt_xm_4242_ros",
    ]
    assert stale_namespaces("xm", LISTED, lambda pid: True) == []  # every owner alive: another run's, kept
    assert stale_namespaces("pl", LISTED, lambda pid: False) == ["vrt_pl_4242_ros"]
    assert stale_namespaces("x", LISTED, lambda pid: False) == []  # a tag is matched whole
    assert stale_namespaces("xm", "", lambda pid: False) == []
