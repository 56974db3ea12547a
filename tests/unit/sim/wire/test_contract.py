"""sim.wire.contract: the engine-controller rules every side keeps."""

from __future__ import annotations

import numpy as np
import pytest

from sim.control.commander import _parser as commander_parser
from sim.errors import SimError
from sim.geometry import frames
from sim.wire.contract import MessageError, PoseConvention, positions_by_name


@pytest.mark.parametrize("convention", list(PoseConvention))
@pytest.mark.parametrize("angles", [(0.1, -0.3, 0.7), (0.0, 0.0, 0.0), (-2.5, 1.2, 3.0)])
def test_a_pose_orientation_survives_encoding_in_either_convention(convention, angles):
    quaternion = frames.euler_xyz_to_quat(*angles)
    decoded = convention.decode(convention.encode(quaternion))
    np.testing.assert_allclose(np.abs(np.dot(decoded, quaternion)), 1.0, atol=1e-12)  # q and -q: one rotation


def test_the_euler_convention_carries_xyz_angles_and_a_zero_w():
    fields = PoseConvention.EULER.encode(frames.euler_xyz_to_quat(np.pi / 4, np.pi / 5, np.pi / 3))
    np.testing.assert_allclose(fields, [np.pi / 4, np.pi / 5, np.pi / 3, 0.0], atol=1e-12)


def test_a_quaternion_is_normalised_on_the_way_in():
    np.testing.assert_allclose(PoseConvention.QUATERNION.decode([0.0, 0.0, 0.0, 3.0]), [0.0, 0.0, 0.0, 1.0])


@pytest.mark.parametrize(
    "convention, fields, why",
    [
        (PoseConvention.QUATERNION, [0.0, 0.0, 0.0, 0.0], "not a quaternion"),
        (PoseConvention.QUATERNION, [np.nan, 0.0, 0.0, 1.0], "not 4 finite numbers"),
        (PoseConvention.EULER, [np.inf, 0.0, 0.0, 0.0], "not 4 finite numbers"),
        (PoseConvention.EULER, [0.0, 0.0, 0.0], "not 4 finite numbers"),
    ],
)
def test_fields_that_carry_no_orientation_are_a_message_error(convention, fields, why):
    with pytest.raises(MessageError, match=why):
        convention.decode(fields)


def test_joint_positions_are_read_by_name_whatever_the_order_and_extra_joints():
    positions = positions_by_name(["finger", "j2", "j1"], [0.04, -0.5, 1.25], ["j1", "j2"])
    assert positions.tolist() == [1.25, -0.5]


@pytest.mark.parametrize("names, positions", [(["j1"], [0.1]), (["j1", "j2"], [0.1])])
def test_a_joint_state_that_does_not_cover_the_joints_is_a_message_error(names, positions):
    with pytest.raises(MessageError, match="not covering"):
        positions_by_name(names, positions, ["j1", "j2"])


def test_message_errors_are_sim_errors_and_value_errors():
    assert issubclass(MessageError, SimError) and issubclass(MessageError, ValueError)


def test_the_commanders_old_pose_flag_still_works_with_a_deprecation_warning(capsys):
    old = commander_parser().parse_args(["--robot", "panda", "--scenario", "sweep", "--pose-euler"])
    assert old.pose_convention == "euler"
    assert (
        capsys.readouterr().err
        == "python -m sim.commander: warning: --pose-euler is deprecated; use --pose-convention euler\n"
    )
    new = commander_parser().parse_args(["--robot", "panda", "--scenario", "sweep", "--pose-convention", "euler"])
    default = commander_parser().parse_args(["--robot", "panda", "--scenario", "sweep"])
    assert (new.pose_convention, default.pose_convention) == ("euler", "quaternion")
    assert capsys.readouterr().err == ""
