"""What people see of a session: the experimenter's live 3-D view (a viser page) and the VR condition's WebXR
page with its server."""

from __future__ import annotations

__all__: list[str] = []
