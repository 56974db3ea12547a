"""The accuracy campaign, by its command name: `python -m sim.trials` runs sim.campaign.trials."""

from sim.campaign.trials import main

__all__ = ["main"]

if __name__ == "__main__":
    raise SystemExit(main())
