"""sim.engine.self_contact: link pairs are left out as MoveIt's setup assistant leaves them out, a real fold is still
checked, and the verdict is computed once per URDF."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sim.engine import self_contact as module
from sim.engine.self_contact import SelfContact, classify, self_contact
from sim.robots import load_robot
from sim.study.design.feasibility import CONTACT_MARGIN, SceneWorld
from sim.study.design.scene import load_scene
from tests.robot_files import THIRD_PARTY_URDFS

LINKS = ("base", "a", "b", "c", "d")


def test_adjacent_default_always_and_never_pairs_are_left_out_and_the_rest_checked() -> None:
    verdict = classify(
        LINKS,
        adjacent=[("a", "base"), ("a", "b"), ("b", "c"), ("c", "d")],
        touching_at_default=[("b", "d")],
        touch_counts={("a", "c"): 50, ("base", "c"): 3, ("base", "d"): 100, ("a", "b"): 100},
        samples=100,
    )
    assert verdict.checked == {("a", "c"), ("base", "c")}
    assert verdict.ignored[("a", "b")] == "adjacent" and verdict.ignored[("b", "d")] == "default"
    assert verdict.ignored[("base", "d")] == "always" and verdict.ignored[("a", "d")] == "never"
    assert verdict.checks("c", "base") and not verdict.checks("b", "a")
    assert len(verdict.checked) + len(verdict.ignored) == len(LINKS) * (len(LINKS) - 1) // 2


def test_an_arm_that_folds_onto_itself_is_still_caught(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("VR_SIM_CACHE", str(tmp_path))
    robot = load_robot(str(THIRD_PARTY_URDFS["lbr_iiwa"]))
    verdict = self_contact(robot)
    links = [f"lbr_iiwa_link_{k}" for k in range(8)]
    for a, b in zip(links, links[1:]):
        assert verdict.ignored[(a, b)] == "adjacent"
    assert ("lbr_iiwa_link_0", "lbr_iiwa_link_6") in verdict.checked  # the wrist can come down onto the base
    with SceneWorld(robot, load_scene()) as world:
        assert world.clearance(robot.home)["self"] > CONTACT_MARGIN  # upright: the adjacent links touch, no fold
        folded = np.array([0.0, 2.0, 0.0, -2.0, 0.0, 2.0, 0.0])  # the forearm and the wrist back onto the base
        assert world.clearance(folded)["self"] < CONTACT_MARGIN


def test_the_verdict_is_sampled_once_per_urdf(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("VR_SIM_CACHE", str(tmp_path))
    robot = load_robot("panda")
    first = self_contact(robot, samples=50)
    assert list((tmp_path / "self_contact").glob("*.json"))

    def no_sampling(*_args: object, **_kwargs: object) -> SelfContact:
        raise AssertionError("sampled again")

    monkeypatch.setattr(module, "sample", no_sampling)
    assert self_contact(robot, samples=50) == first
    with pytest.raises(AssertionError, match="sampled again"):
        self_contact(robot, samples=60)  # another decision, another verdict
