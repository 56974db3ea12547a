"""The commander (Simulink stand-in), by its command name: `python -m sim.commander` runs sim.control.commander."""

from sim.control.commander import main

__all__ = ["main"]

if __name__ == "__main__":
    raise SystemExit(main())
