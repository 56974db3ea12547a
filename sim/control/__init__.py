"""The controller side, the Simulink stand-in: the driver that steps a robot through ROS (driver), the
commander that streams a scenario (commander; `python -m sim.commander`), the scenarios themselves
(scenarios, scenario_defaults), and what a run leaves: its log, summary and tracking metrics (run_log,
run_summary, metrics).
"""
