"""Simulated robots, kinematics, physics, the game-engine stand-in, the commander, trials and analysis."""
