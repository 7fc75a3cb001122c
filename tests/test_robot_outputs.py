"""A robot's outputs (``model.descriptions.robot_outputs``), as the io, the viewer and the
command line read them, against the outputs the formulations that estimate them write;
and its sections' ends and count, read from the outputs or from a table's names."""

from __future__ import annotations

from dataclasses import replace

import pytest

from continuum_mhe.errors import UserError
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.model.descriptions import (
    output_names,
    robot_outputs,
    section_bends,
    section_count,
    section_end_columns,
    section_end_indices,
    sections_with_ends,
)
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import ImuPlacement, Robot, Section


def pcc_robot(n_sections: int) -> Robot:
    """A constant-curvature robot of ``n_sections`` with an IMU at each section's end."""
    return Robot(
        tuple(Section(0.1, 3.0) for _ in range(n_sections)),
        tuple(ImuPlacement(k) for k in range(n_sections)),
    )


@pytest.mark.parametrize("n_sections", [1, 2, 3])
def test_a_constant_curvature_robots_outputs_are_its_formulations(n_sections):
    robot = pcc_robot(n_sections)
    for name in ("bend", "direct", *(("paper",) if n_sections == 1 else ())):
        assert robot_outputs(robot) == make_formulation(name, robot).outputs, name
    twisted = make_formulation("direct", robot, imu_twist=True).outputs
    assert robot_outputs(robot, imu_twist=True) == twisted
    assert len(twisted) == len(robot_outputs(robot)) + n_sections  # one twist per IMU


def test_a_constant_curvature_robots_outputs_by_name():
    """Known answers, written out: the paper's five outputs for one section, the tip and
    each section's bend and end for two, and the IMUs' twists last."""
    one = pcc_robot(1)
    assert output_names(robot_outputs(one)) == ("x", "y", "z", "theta", "phi")
    assert output_names(robot_outputs(one, imu_twist=True))[5:] == ("imu_twist",)
    two = output_names(robot_outputs(pcc_robot(2), imu_twist=True))
    assert two == (
        "x", "y", "z",
        "theta_1", "phi_1", "x_1", "y_1", "z_1",
        "theta_2", "phi_2", "x_2", "y_2", "z_2",
        "imu_twist_1", "imu_twist_2",
    )  # fmt: skip


@pytest.mark.parametrize("imu_model", ["tilt", "direct"])
def test_the_shipped_tendon_robots_outputs_are_its_formulations(imu_model):
    robot = read_robot("tendon-two-section")
    for gain in (False, True):
        f = make_formulation("tendon", robot, imu_model=imu_model, estimate_tension_gain=gain)
        assert robot_outputs(robot, tension_gain=gain) == f.outputs
    names = output_names(robot_outputs(robot, tension_gain=True))
    assert names[:3] == ("x", "y", "z")
    assert names[-5:] == ("fx", "fy", "fz", "tension_gain_1", "tension_gain_2")
    assert "psi_2" in names and "theta" not in names  # every section numbered, and twisted


def test_tension_gains_are_those_of_the_sections_with_tendons_anchored():
    shipped = read_robot("tendon-two-section")
    tip_only = replace(shipped, tendons=tuple(t for t in shipped.tendons if t.section == 1))
    f = make_formulation("tendon", tip_only, estimate_tension_gain=True)
    assert robot_outputs(tip_only, tension_gain=True) == f.outputs
    assert output_names(f.outputs)[-1:] == ("tension_gain_2",)
    assert "tension_gain_1" not in output_names(f.outputs)


def test_an_option_the_robots_model_lacks_is_refused():
    with pytest.raises(UserError, match="tension gains are a tendon robot's"):
        robot_outputs(pcc_robot(2), tension_gain=True)
    tendon = read_robot("tendon-two-section")
    with pytest.raises(UserError, match="no IMU twist"):
        robot_outputs(tendon, imu_twist=True)
    with pytest.raises(UserError, match="no option 'imu_twist'"):  # as its formulation
        make_formulation("tendon", tendon, imu_twist=True)


def test_a_sections_end_is_its_three_positions_among_the_outputs():
    two = robot_outputs(pcc_robot(2))
    tendon = robot_outputs(read_robot("tendon-two-section"), tension_gain=True)
    for outputs in (two, tendon):
        for k in (1, 2):
            names = tuple(outputs[i].name for i in section_end_indices(outputs, k))
            assert names == (f"x_{k}", f"y_{k}", f"z_{k}") == section_end_columns(k)
    # not the twist psi_2 or the gain tension_gain_2 of section 2, nor a section past the last
    assert section_end_indices(tendon, 3) == ()
    assert section_end_indices(robot_outputs(pcc_robot(1)), 1) == ()  # its end is the tip


def test_a_tables_section_ends_and_count_from_its_names():
    names = ["t", "x", "y", "z", "x_0", "y_0", "z_0", "x_1", "y_1", "x_3", "y_3", "z_3"]
    assert sections_with_ends(names) == [3]  # section 1 lacks z_1; no section 0
    assert section_count(["x", "y", "z", "theta", "phi"]) == 1
    assert section_count(["theta_1", "phi_1", "theta_2", "phi_2", "theta_4"]) == 2
    assert section_count(["x", "y", "z"]) == 0


@pytest.mark.parametrize("n_sections", [1, 2, 3])
def test_section_bends_of_each_section(n_sections):
    outputs = robot_outputs(pcc_robot(n_sections))
    values = [0.0] * len(outputs)
    names = output_names(outputs)
    for k in range(n_sections):  # theta 0.1 (k + 1), phi 0.5 rad
        th, ph = ("theta", "phi") if n_sections == 1 else (f"theta_{k + 1}", f"phi_{k + 1}")
        values[names.index(th)], values[names.index(ph)] = 0.1 * (k + 1), 0.5
    bends = section_bends(outputs, values)
    assert bends.shape == (n_sections, 2)
    for k in range(n_sections):
        assert bends[k] == pytest.approx([0.1 * (k + 1) * 0.8775825618903728,
                                          0.1 * (k + 1) * 0.479425538604203])  # fmt: skip
