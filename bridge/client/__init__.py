"""The Python client of the ROS-TCP protocol (bridge.client.connector), without rospy: `TcpClient` connects to the
endpoint as Unity's ROS-TCP-Connector would, `ClientError` is what it raises, `PingResult` what a ping gives."""

from __future__ import annotations

from bridge.client.connector import ClientError, PingResult, TcpClient

__all__ = ["ClientError", "PingResult", "TcpClient"]
