"""What the endpoint's node owes the ROS master: its registrations, kept through outages and restarts. Pure.

rospy registers a publisher, subscriber or service with the master once, on the thread that creates it, retrying
forever while the master does not answer, and never again: a master restarted on the same port (an everyday event
in a lab) knows none of them, and a frozen one blocks whoever creates the next one. The book records what the node
wants registered and what the master in front of it has accepted; bridge.ros.master runs the calls it asks for, on a
thread of its own, and tells it what the master said. A different master (another identity) owes everything again.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Hashable

__all__ = ["Registration", "RegistrationBook", "KINDS"]

KINDS = ("publisher", "subscriber", "service")


@dataclass(frozen=True)
class Registration:
    """One registration as the master's API takes it: a topic's type, or a service's rosrpc URI, as `detail`."""

    kind: str  # one of KINDS
    name: str  # resolved graph name
    detail: str


class RegistrationBook:
    """The node's registrations and the master's view of them; one master identity at a time."""

    def __init__(self, registered: tuple[Registration, ...] = (), identity: Hashable | None = None) -> None:
        # (kind, name) -> registration, as the node has it now
        self._wanted: dict[tuple[str, str], Registration] = {(r.kind, r.name): r for r in registered}
        # what the master of `identity` holds (or refused: it will not take them, asking again is pointless)
        self._accepted: dict[tuple[str, str], Registration] = dict(self._wanted)
        self._withdrawn: list[Registration] = []  # accepted by the master, no longer wanted: to unregister
        self.identity = identity

    def __len__(self) -> int:
        return len(self._wanted)

    def counts(self) -> dict[str, int]:
        """Registrations wanted, per kind."""
        return {kind: sum(1 for wanted_kind, _ in self._wanted if wanted_kind == kind) for kind in KINDS}

    # --- what the node does -------------------------------------------------------------------------------------
    def add(self, registration: Registration) -> None:
        self._wanted[(registration.kind, registration.name)] = registration

    def remove(self, registration: Registration) -> None:
        key = (registration.kind, registration.name)
        self._wanted.pop(key, None)
        accepted = self._accepted.pop(key, None)
        if accepted is not None:
            self._withdrawn.append(accepted)

    # --- what the master says -----------------------------------------------------------------------------------
    def master_is(self, identity: Hashable) -> bool:
        """The master answering now is `identity`; True when it is another one than before (it owes everything)."""
        if identity == self.identity:
            return False
        changed = self.identity is not None
        self.identity = identity
        self._accepted.clear()
        self._withdrawn.clear()  # a new master holds nothing of ours to take back
        return changed

    def to_register(self) -> list[Registration]:
        """What the master does not hold yet, in a stable order (publishers, subscribers, services; by name)."""
        owed = [r for key, r in self._wanted.items() if self._accepted.get(key) != r]
        return sorted(owed, key=lambda r: (KINDS.index(r.kind), r.name))

    def holds(self, kind: str, name: str) -> bool:
        """Whether the master holds the node's registration of `name` as a `kind` (as the node has it now)."""
        wanted = self._wanted.get((kind, name))
        return wanted is not None and self._accepted.get((kind, name)) == wanted

    def wanted(self) -> list[Registration]:
        """Every registration the node has now."""
        return list(self._wanted.values())

    def to_unregister(self) -> list[Registration]:
        """What the master holds that the node withdrew: to be taken back before anything is registered (a name
        withdrawn and registered again must end registered)."""
        return list(self._withdrawn)

    def registered(self, registration: Registration) -> None:
        """The master accepted it (or refused it for good: it is not asked again). Withdrawn while the call was on
        its way, it is owed back at once."""
        key = (registration.kind, registration.name)
        if self._wanted.get(key) == registration:
            self._accepted[key] = registration
        elif registration not in self._withdrawn:
            self._withdrawn.append(registration)

    def unregistered(self, registration: Registration) -> None:
        if registration in self._withdrawn:
            self._withdrawn.remove(registration)
