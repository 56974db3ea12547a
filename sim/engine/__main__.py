"""`python -m sim.engine`: the game-engine stand-in (sim.engine.stand_in)."""

from sim.engine.stand_in import main

if __name__ == "__main__":
    raise SystemExit(main())
