"""rospy.init_node for the sim's ROS nodes (the physics node, the commander, the description node, the study's
runner), with one fix to how they end.

rospy's shutdown joins its registration thread, which checks the shutdown flag every 0.5 s and is last woken before
the flag goes up: every node took up to half a second to exit after its work was done. A shutdown hook, run once the
flag is up, wakes it.
"""

from __future__ import annotations

from typing import Any

import rospy
from rospy.impl.registration import RegManager

__all__ = ["init_node"]


def init_node(name: str) -> None:
    """rospy.init_node(name) without rospy's signal handlers (each node handles SIGINT and SIGTERM itself)."""
    rospy.init_node(name, disable_signals=True)
    manager = _registration_manager()
    if manager is not None:
        rospy.core.add_shutdown_hook(lambda reason: _wake(manager))


def _registration_manager() -> RegManager | None:
    """The node's RegManager: its XML-RPC server's handler holds it, and init_node made that server's shutdown a
    shutdown hook (the manager itself joins the registration listeners only once registered, on its own thread)."""
    for hook in rospy.core._shutdown_hooks:
        server: Any = getattr(hook, "__self__", None)
        manager = getattr(getattr(server, "handler", None), "reg_man", None)
        if isinstance(manager, RegManager):
            return manager
    return None


def _wake(manager: RegManager) -> None:
    with manager.cond:
        manager.cond.notify_all()
