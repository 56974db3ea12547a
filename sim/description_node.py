"""The robot's description for RViz, by its command name: `python -m sim.description_node` runs
sim.engine.description_node."""

from sim.engine.description_node import main

__all__ = ["main"]

if __name__ == "__main__":
    raise SystemExit(main())
