"""Geometry without I/O: ROS/Unity frames and rotations (frames), forward and inverse kinematics from a URDF
(kinematics), and polynomial trajectories (trajectory).
"""
