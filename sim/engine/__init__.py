"""The game-engine side: pybullet physics with Unity's ArticulationDrive law (physics), the simulation clock
(clock), joint commands waiting for their step (commands), the stand-in for Unity that talks to ROS only through
the endpoint (stand_in; `python -m sim.engine`), the same physics as a rospy node (node) and the RViz description
node (description_node).
"""
