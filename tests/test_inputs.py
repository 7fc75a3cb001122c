"""The input pipeline (``continuum_mhe.io.inputs``): what it says an input is, and that
it gives the same measurements as reading the file by hand."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from continuum_mhe.errors import InputError
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.inputs import load_input, open_input, serial_input
from continuum_mhe.io.raw_imu import RawImuSettings
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.model.direct import DirectFormulation
from continuum_mhe.model.registry import make_formulation

DATA = Path(__file__).parents[1] / "src/continuum_mhe/data"


def test_a_tilt_table_in_ms_and_degrees_is_described_and_converted(tmp_path: Path) -> None:
    path = tmp_path / "tilt.csv"
    path.write_text("t_ms,roll,pitch\n0,10,-20\n50,nan,5\n100,30,40\n")
    options = InputOptions(degrees=True, skip_bad=True)
    with open_input(path, options, make_formulation("bend")) as stream:
        samples = list(stream.samples)
        d = stream.description
    assert (d.kind, d.columns, d.imu_model) == ("tilt-csv", ("t", "roll", "pitch"), "tilt")
    assert d.units == "t in ms; roll, pitch in deg"
    assert [t for t, _ in samples] == [0.0, 0.05, 0.1]
    assert_allclose(samples[2][1], np.radians([30.0, 40.0]))
    assert d.problems.count == 1 and "line 3" in d.problems.first[0]  # the NaN row
    assert d.readings is not None and d.readings.samples == 3
    assert any("bad rows" in c for c in d.summary())


def test_raw_gyros_take_the_direct_model_and_say_so() -> None:
    robot = read_robot(DATA / "robots/two_section.toml")
    path = DATA / "rod2/planar-s_raw.csv"
    with open_input(path, InputOptions(), make_formulation("bend", robot)) as stream:
        d = stream.description
        n = sum(1 for _ in stream.samples)
    assert isinstance(stream.formulation, DirectFormulation)
    assert (d.kind, d.imu_model) == ("raw-csv", "direct")
    assert d.columns[:4] == ("t", "ax_1", "ay_1", "az_1") and "gz_2" in d.columns
    assert d.units == "t in s; acceleration in m/s^2, gyro in rad/s"
    assert d.problems.count == 0 and d.summary() == ()
    assert n == len(load_input(path, InputOptions(), make_formulation("bend", robot)).t)


def test_tensions_are_appended_at_each_sample_time() -> None:
    """The tendon robot's samples carry the tensions file's rows interpolated at their
    time: here the file's own times, so its rows come back exactly."""
    from continuum_mhe.io.tensions import read_tensions

    robot = read_robot(DATA / "robots/tendon_two_section.toml")
    tensions = DATA / "tendon/force-08_tensions.csv"
    options = InputOptions(tensions=str(tensions))
    base = make_formulation("bend", robot)
    with open_input(DATA / "tendon/force-08_tilt.csv", options, base) as stream:
        samples = list(stream.samples)
        d = stream.description
    assert d.tensions == str(tensions) and stream.formulation.name == "tendon"
    table = read_tensions(tensions, robot.n_tendons)
    k = robot.n_tendons
    for t, z in samples[:: len(samples) // 5]:
        tau = table.at(t)[0]
        assert_allclose(z[4 : 4 + k], tau)  # after the two IMUs' roll and pitch


def test_tensions_are_checked_before_the_recording() -> None:
    """A tendon robot's missing tensions are said before the recording's rows are read
    (its header alone shows it carries none); tensions for a robot without tendons
    before the recording is opened."""
    robot = read_robot(DATA / "robots/tendon_two_section.toml")
    unread = DATA / "tendon/force-08_tilt.csv"  # IMU columns alone: the tensions' error
    with pytest.raises(InputError, match="robot.toml: the robot has 6 tendons"):
        open_input(unread, InputOptions(), make_formulation("bend", robot), "robot.toml")
    with pytest.raises(InputError, match="the robot has no \\[\\[tendon\\]\\]"):
        open_input(DATA / "none.csv", InputOptions(tensions="t.csv"), make_formulation("bend"))


def test_live_lines_are_resolved_as_a_table_of_their_kind() -> None:
    robot = read_robot(DATA / "robots/two_section.toml")
    base = make_formulation("bend", robot)
    raw = serial_input("/dev/x", "raw", InputOptions(), base)
    assert isinstance(raw.formulation, DirectFormulation) and raw.converters is not None
    assert len(raw.converters) == robot.n_imus
    assert raw.tensions is None and raw.tensions_on_line == 0  # no tendons
    tilt = serial_input("/dev/x", "tilt", InputOptions(), base)
    assert tilt.formulation.name == "bend" and tilt.converters is None
    direct = InputOptions(raw=RawImuSettings(imu_model="direct"))
    with pytest.raises(InputError, match="--imu-model direct needs --format raw"):
        serial_input("/dev/x", "tilt", direct, base)


def test_library_input_mistakes_are_one_line(tmp_path: Path) -> None:
    """Mistakes from a library user's trial are one line each: a tendon robot without
    tensions names the robot file and the tendons (not "None"); a tendon formulation
    handed to load_input names the model it calls for (not numpy's 'cannot reshape
    array'); write_measurements refuses z with more rows than t, writing nothing."""
    from continuum_mhe.io.estimate_csv import write_measurements

    robot = read_robot(DATA / "robots/tendon_two_section.toml")
    unread = DATA / "tendon/force-08_tilt.csv"  # IMU columns alone
    with pytest.raises(InputError, match="^the robot file: the robot has 6 tendons: .*Python"):
        open_input(unread, InputOptions(), make_formulation("bend", robot))
    raw = DATA / "tendon/unloaded_raw.csv"
    tensions = InputOptions(tensions=str(DATA / "tendon/unloaded_tensions.csv"))
    with pytest.raises(InputError, match="not 'tendon': the model it calls for"):
        load_input(raw, tensions, make_formulation("tendon", robot))
    with pytest.raises(ValueError, match="t has 40 samples and z 41 rows"):
        write_measurements(tmp_path / "m.csv", np.arange(40.0), np.zeros((41, 2)))
    assert not (tmp_path / "m.csv").exists()
    # lists are arrays; a 1-D z, an array for a series, a series of another robot's
    # estimates with another's outputs: one line each (not AttributeError or IndexError)
    from continuum_mhe import make_estimator, simulate, simulate_robot
    from continuum_mhe.errors import UserError
    from continuum_mhe.io.estimate_csv import write_estimates
    from continuum_mhe.results import EstimateSeries, Measurement

    rec = simulate("paper3d", duration=0.5)
    write_measurements(tmp_path / "m.csv", list(rec.t), rec.z.tolist())
    assert (tmp_path / "m.csv").read_text().startswith("t,roll,pitch\n0,")
    with pytest.raises(ValueError, match=r"t must be \(n,\) and z \(n, m\); got shapes"):
        write_measurements(tmp_path / "m1.csv", rec.t, rec.z[:, 0])
    series = make_estimator("ekf", make_formulation("bend")).run(rec.t, rec.z)
    with pytest.raises(UserError, match="series must be an EstimateSeries .*got a ndarray"):
        write_estimates(tmp_path / "e.csv", series.output)  # type: ignore[arg-type]
    two = read_robot("two-section")
    rec2 = simulate_robot("spatial", two, duration=0.2)
    est = make_estimator("ekf", make_formulation("bend", two))
    steps = [est.step(Measurement(float(t), z)) for t, z in zip(rec2.t, rec2.z)]
    # the estimates name their outputs: a series of them needs no outputs=
    series2 = EstimateSeries.from_estimates("ekf", steps)
    assert series2.names == [o.name for o in est.formulation.outputs]
    np.testing.assert_array_equal(series2.column("theta_2")[-1], steps[-1].value("theta_2"))
    with pytest.raises(UserError, match="has 13 outputs, but outputs describes 5: pass"):
        EstimateSeries.from_estimates("ekf", steps, outputs=make_formulation("bend").outputs)
    assert not (tmp_path / "m1.csv").exists() and not (tmp_path / "e.csv").exists()


def test_a_series_gives_an_output_s_standard_deviation_by_name() -> None:
    """``EstimateSeries.std_column`` is the ``output_std`` column of the name
    ``column`` takes; an unknown name is a KeyError, a series without standard
    deviations gives NaN."""
    from continuum_mhe.results import EstimateSeries

    t = np.arange(3.0)
    output, std = np.arange(15.0).reshape(3, 5), 0.1 * np.arange(15.0).reshape(3, 5)
    status = np.array(["ok"] * 3)
    series = EstimateSeries("ekf", t, output, status, np.zeros(3), output_std=std)
    np.testing.assert_array_equal(series.std_column("z"), std[:, 2])
    assert series.names[2] == "z"
    for get in (series.std_column, series.column):  # the columns there are, named
        with pytest.raises(KeyError, match=r"no output column 'fx' \(the columns: x, y, z, "):
            get("fx")
    bare = EstimateSeries("ekf", t, output, status, np.zeros(3))
    assert np.isnan(bare.std_column("x")).all()


@pytest.mark.parametrize(
    ("field", "value", "said"),
    [
        ("degrees", "no", "InputOptions degrees must be True or False, got str 'no'"),
        ("estimate_gyro_bias", "no", "InputOptions estimate_gyro_bias must be True, False or None"),
        ("raw", None, "InputOptions raw must be a RawImuSettings, got NoneType None"),
        ("topics", "/imu", "InputOptions topics must be a sequence of str"),
        ("gyro_std", -1.0, "InputOptions gyro_std must be a positive finite number"),
    ],
)
def test_input_options_check_their_fields(field: str, value: object, said: str) -> None:
    """A string for a switch read as true (``degrees="no"`` turned every reading by
    pi/180), ``raw=None`` failed inside the reader: each field is checked where the
    options are made, a UserError naming it; a list of topics is taken as a tuple."""
    from continuum_mhe.errors import UserError

    with pytest.raises(UserError) as refused:
        InputOptions(**{field: value})
    assert str(refused.value).startswith(said)
    assert InputOptions(topics=["/a", "/b"]).topics == ("/a", "/b")
