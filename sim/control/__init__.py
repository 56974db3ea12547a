"""The controller: what Simulink was in the thesis. It owns /clock, streams joint commands and reads joint states.

Its ROS node (controller_node) and its timing, lockstep or real time (stepper), are shared by its two kinds: the
commander, which streams a scenario (commander; `python -m sim.commander`), and the study runner (sim.study.run.runner).
Also here: the scenarios themselves (scenarios/) and what a commander's run leaves: its log, summary and tracking
metrics (run_log, run_summary, metrics).
"""
