"""The accuracy campaign: trials of every robot, mode and use case (trials; `python -m sim.trials`), their
analysis from the recorded bags (analysis), and the end-to-end demo (demo; `python -m sim.demo`).
"""
