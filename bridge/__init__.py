"""The ROS-TCP endpoint: protocol v0.7.0 (ROS 1), drop-in for Unity's ROS-TCP-Endpoint."""
