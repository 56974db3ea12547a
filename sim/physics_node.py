"""The physics as a rospy node, by its command name: `python -m sim.physics_node` runs sim.engine.node."""

from sim.engine.node import main

__all__ = ["main"]

if __name__ == "__main__":
    raise SystemExit(main())
