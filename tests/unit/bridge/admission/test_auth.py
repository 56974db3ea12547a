"""The shared token's guard (bridge.admission.auth): constant-time comparison, and a back-off per address for wrong
tokens."""

from __future__ import annotations

from bridge.admission.auth import BACKOFF_FIRST_S, BACKOFF_MAX_S, AuthGuard


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_the_right_token_is_let_in_at_once() -> None:
    assert AuthGuard("secret").check("10.0.0.1", "secret") == 0.0


def test_each_wrong_token_doubles_the_hold_back_up_to_its_maximum() -> None:
    guard = AuthGuard("secret", Clock())
    delays = [guard.check("10.0.0.1", "guess") for _ in range(12)]
    assert delays[:3] == [BACKOFF_FIRST_S, 2 * BACKOFF_FIRST_S, 4 * BACKOFF_FIRST_S]
    assert delays[-1] == BACKOFF_MAX_S and all(b >= a for a, b in zip(delays, delays[1:]))
    assert guard.failures("10.0.0.1") == 12


def test_the_back_off_is_per_address_and_a_right_token_clears_it() -> None:
    guard = AuthGuard("secret", Clock())
    for _ in range(5):
        guard.check("10.0.0.1", "guess")
    assert guard.check("10.0.0.2", "guess") == BACKOFF_FIRST_S  # another address starts afresh
    assert guard.check("10.0.0.1", "secret") == 0.0  # not held up by the guesses before it
    assert guard.failures("10.0.0.1") == 0
    assert guard.check("10.0.0.1", "guess") == BACKOFF_FIRST_S


def test_an_empty_or_unicode_token_is_just_wrong() -> None:
    guard = AuthGuard("sécret")
    assert guard.check("h", "") > 0 and guard.check("h", "secret") > 0 and guard.check("h", "sécret") == 0.0


def test_the_records_stay_bounded_when_many_addresses_guess() -> None:
    clock = Clock()
    guard = AuthGuard("secret", clock)
    for index in range(10_000):
        clock.now += 1
        guard.check(f"10.{index // 65536}.{index // 256 % 256}.{index % 256}", "guess")
    assert len(guard._failures) <= 4096
    assert guard.failures("10.0.39.15") == 1  # the newest are remembered
