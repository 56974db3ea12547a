"""The end-to-end demo, by its command name: `python -m sim.demo` runs sim.campaign.demo."""

from sim.campaign.demo import main

__all__ = ["main"]

if __name__ == "__main__":
    raise SystemExit(main())
