"""User mistakes in library calls (the Python API): wrong types, readings in degrees or
in other units, times not in seconds or out of order, arrays of the wrong shape, robots
built in code with a robot file's slips, writers given what their readers would not
read back: a UserError in one line naming the argument, not an error from inside."""

from __future__ import annotations

import math
import re
import warnings

import numpy as np
import pytest

from continuum_mhe import (
    Measurement,
    MHESettings,
    NoiseSettings,
    make_estimator,
    make_formulation,
    simulate,
)
from continuum_mhe.cli import main
from continuum_mhe.errors import InputError, UserError
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.settings import RobotSettings
from continuum_mhe.simulation.scenarios import simulate_robot


def test_library_call_given_degrees_says_so() -> None:
    est = make_estimator("ekf", make_formulation("bend", RobotSettings()))
    with pytest.raises(UserError, match="degrees\\? measurements are in radians"):
        est.step(Measurement(0.0, np.array([30.0, 20.0])))
    # beyond pi (no gravity direction needs it): refused, as degrees
    for z in ([3.3, 0.0], [0.0, 3.3]):
        est.reset()
        with pytest.raises(UserError, match="beyond pi, out of range: degrees"):
            est.step(Measurement(0.0, np.array(z)))
    for m in ("mhe", "ukf"):  # every estimator, in run() as in step()
        rec = simulate("paper3d", duration=0.4)
        with pytest.raises(UserError, match="out of range"):
            make_estimator(m, make_formulation("bend")).run(rec.t, np.degrees(rec.z))
    # every reading written as the same gravity direction with its pitch beyond pi/2
    # (pi - pitch, the roll turned by pi): accepted, and the same estimates
    rec = simulate("paper3d", duration=2.0)
    roll, pitch = rec.z[:, 0], rec.z[:, 1]
    other = np.column_stack([(roll + 2 * math.pi) % (2 * math.pi) - math.pi,
                             np.copysign(math.pi, pitch) - pitch])  # fmt: skip
    assert np.all(np.abs(other[:, 1]) > math.pi / 2)
    a, b = (make_estimator("ekf", make_formulation("bend")).run(rec.t, z) for z in (rec.z, other))
    np.testing.assert_allclose(a.output, b.output, rtol=0, atol=1e-9)
    est.reset()  # radians, even the largest: accepted
    e = est.step(Measurement(0.0, np.array([math.pi, math.pi / 2])))
    # pitch pi/2 (the gimbal lock): a quarter-circle bend, theta = pi/2, phi = +-pi, the
    # tip at (r, 0, r) with the radius r = 2 L / pi, on the bound theta_max = pi/2
    assert e.status == "at-bound"
    x, y, z, theta, phi = e.output
    r = 2 * RobotSettings().length / math.pi
    np.testing.assert_allclose([x, y, z], [r, 0.0, r], rtol=0, atol=1e-9)
    np.testing.assert_allclose([theta, abs(phi)], [math.pi / 2, math.pi], rtol=0, atol=1e-9)


def test_continue_run_checks_its_arrays_as_run_does() -> None:
    """``continue_run`` (the guide's block-by-block run) refuses arrays whose lengths or
    widths do not fit in one UserError, as ``run`` does, and takes lists."""
    rec = simulate("paper3d", duration=1.0)
    est = make_estimator("ekf", make_formulation("bend"))
    with pytest.raises(UserError, match="t has 10 samples but z has 21"):
        est.continue_run(rec.t[:10], rec.z)
    with pytest.raises(UserError, match=r"z must have shape \(n, 2\) for the bend formulation"):
        est.continue_run(rec.t, rec.z[:, :1])
    with pytest.raises(UserError, match=r"z is None: give the readings, an array \(n, 2\)"):
        est.continue_run(rec.t, None)  # type: ignore[arg-type]
    est.reset()
    batch = est.continue_run(list(rec.t), rec.z.tolist())
    np.testing.assert_array_equal(batch.output, est.run(rec.t, rec.z).output)


def test_a_transposed_z_is_named_as_transposed() -> None:
    """A recording's z given as (nz, n), the readings of each column a row, is refused
    by ``run`` and ``continue_run`` in one UserError that shows z's shape and says it
    looks transposed, and the estimator steps on as it was."""
    rec = simulate("paper3d", duration=1.0)
    est = make_estimator("ekf", make_formulation("bend"))
    for call in (est.run, est.continue_run):
        with pytest.raises(UserError, match=r"z's shape \(2, 21\).*transposed\? \(z.T"):
            call(rec.t, rec.z.T)
    with pytest.raises(UserError, match=r"z's shape \(21, 2\)") as refused:
        est.run(rec.t[:10], rec.z)  # lengths that differ otherwise: no transposition named
    assert "transposed" not in str(refused.value)
    est.reset()
    batch = est.continue_run(rec.t, rec.z)
    np.testing.assert_array_equal(batch.output, est.run(rec.t, rec.z).output)


@pytest.mark.parametrize(
    ("block", "starts", "match"),
    [
        (-1, None, "block must be a positive integer"),
        (0, None, "block must be a positive integer"),
        (2.5, None, "block must be a positive integer"),
        (True, None, "block must be a positive integer"),
        (10, [0], "stepped the first 10 of the 21 samples"),  # samples left out
        (10, [0, 15], "a block starts at 15 where sample 10 is next"),  # a gap
        (10, [0, 0, 10, 20], "a block starts at 0 where sample 10 is next"),  # repeated
        (10, [10, 0, 20], "a block starts at 10 where sample 0 is next"),  # out of order
        (10, [0, 10, 20, 30], "a block starts at 30 where sample 21 is next"),  # beyond
    ],
)
def test_continue_run_refuses_blocks_that_do_not_cover_the_samples(block, starts, match) -> None:
    """``continue_run`` steps every sample once, in order, or refuses in one
    UserError: a block size that is not a positive integer, or starts that skip,
    repeat, reorder or pass the samples (the rows left unstepped would read as ``ok``
    estimates of uninitialised memory). Starts given as a list are checked before any
    sample is stepped (not the blocks before a bad one stepped, their estimates lost,
    and the same call again refused as going back in time)."""
    rec = simulate("paper3d", duration=1.0)
    est = make_estimator("ekf", make_formulation("bend"))
    with pytest.raises(UserError, match=match):
        est.continue_run(rec.t, rec.z, starts=starts, block=block)
    batch = est.continue_run(rec.t, rec.z, starts=range(0, 21, 10), block=10)  # no reset
    np.testing.assert_array_equal(batch.output, est.run(rec.t, rec.z).output)


def test_continue_run_refuses_a_should_stop_that_is_no_function() -> None:
    """``should_stop=5`` is a UserError saying what should_stop must be, not a TypeError
    from inside the compiled loop."""
    rec = simulate("paper3d", duration=1.0)
    est = make_estimator("ekf", make_formulation("bend"))
    with pytest.raises(UserError, match=r"should_stop must be a function that says when"):
        est.continue_run(rec.t, rec.z, should_stop=5)  # type: ignore[arg-type]
    assert len(est.continue_run(rec.t, rec.z).output) == len(rec.t)


def test_theta_max_in_degrees_in_the_library() -> None:
    with pytest.raises(UserError, match="degrees"):
        RobotSettings(theta_max=90)


def test_a_multi_section_scenario_from_simulate_names_simulate_robot() -> None:
    """``simulate("spatial")`` names the library call to use, ``simulate_robot('spatial',
    robot)`` (not the command line's --robot), which ``continuum_mhe`` exports and which
    simulates the scenario."""
    import continuum_mhe
    from continuum_mhe.errors import UserError
    from continuum_mhe.io import read_robot

    with pytest.raises(UserError, match=r"simulate_robot\('spatial', robot\)"):
        continuum_mhe.simulate("spatial")
    rec = continuum_mhe.simulate_robot("spatial", read_robot("two-section"), duration=1.0)
    assert rec.z.shape == (21, 4) and np.all(np.isfinite(rec.z))


def test_an_imu_on_a_missing_section_in_code_says_the_index_is_0_based() -> None:
    """``ImuPlacement(section=2)`` on a two-section robot names the 0-based index the
    user wrote, not 'section 3' (robot files are 1-based, code 0-based)."""
    from continuum_mhe import ImuPlacement, Robot, Section
    from continuum_mhe.errors import UserError

    sections = (Section(0.1), Section(0.1))
    with pytest.raises(UserError) as info:
        Robot(sections, (ImuPlacement(section=0), ImuPlacement(section=2)))
    assert str(info.value) == (
        "IMU 2: ImuPlacement.section=2 is a 0-based section index, but the robot has 2 "
        "section(s) (indices 0 to 1; robot files number sections from 1)"
    )
    assert Robot(sections, (ImuPlacement(section=0), ImuPlacement(section=1))).n_imus == 2


@pytest.mark.parametrize("method", ["mhe", "ekf", "ukf"])
def test_raw_readings_in_the_wrong_units_given_to_an_estimator_are_refused(method) -> None:
    """The direct model reads a unit specific force and rad/s: an accelerometer's reading
    in m/s^2 (step and run), or gyros in deg/s (run; step below), is one UserError naming the
    readings, and the readings built by ``direct_measurements`` pass."""
    from continuum_mhe.model.direct import direct_measurements

    f = make_formulation("direct")
    est = make_estimator(method, f)
    acc = np.array([[0.3, -0.2, 9.79]])
    meters_per_s2 = r"^measurement at t=0\.0 s: fx, fy, fz have magnitude 9\.8"
    with pytest.raises(UserError, match=meters_per_s2):
        est.step(Measurement(0.0, np.array([0.3, -0.2, 9.79, 0.01, 0.0, 0.02])))
    t = np.arange(40) * 0.02
    degrees_per_s = np.tile(direct_measurements(acc, np.radians([[30.0, 0.0, 0.0]])), (40, 1))
    degrees_per_s[:, 3:] = np.degrees(degrees_per_s[:, 3:])
    with pytest.raises(
        UserError,
        match=r"^wx, wy, wz \(the gyro's gx, gy, gz\): gyro magnitude is about 30 \(median\)"
        r".*deg/s",
    ):
        est.run(t, degrees_per_s)
    good = np.tile(direct_measurements(acc, [[0.01, 0.0, 0.02]]), (40, 1))
    good[0] = np.nan  # a dropout first: step checks the first full reading
    series = est.run(t, good)
    assert np.isfinite(series.output[5:]).all()
    est.reset()
    for tk, zk in zip(t, good):
        est.step(Measurement(float(tk), zk))
    est.reset()  # a reading in m/s^2 after the dropout is the first full one: refused
    est.step(Measurement(0.0, good[0]))
    with pytest.raises(UserError, match=r"^measurement at t=0\.02 s: fx, fy, fz have magnitude"):
        est.step(Measurement(0.02, np.array([0.3, -0.2, 9.79, 0.01, 0.0, 0.02])))


@pytest.mark.parametrize("method", ["mhe", "ekf"])
def test_a_resting_gyro_in_degrees_per_second_is_refused_by_run_and_step(method) -> None:
    """``direct`` readings of an IMU at rest whose gyro is in deg/s (a bias of about 2
    deg/s: its median rate is far below the deg/s threshold) are refused by ``run`` (the
    whole recording) and by ``step`` (at the sample that completes the first check),
    because read as rad/s the gyro would turn the still specific force by tens of
    degrees a second; the same readings in rad/s run through."""
    from continuum_mhe.estimators.reading_units import ReadingUnitsError
    from continuum_mhe.io.raw_units import UNIT_CHECK_SAMPLES
    from continuum_mhe.model.direct import direct_measurements

    rng = np.random.default_rng(5)
    n = UNIT_CHECK_SAMPLES + 20
    t = np.arange(n) * 0.02
    acc = np.array([0.3, -0.2, 9.79]) + rng.normal(0.0, 0.05, (n, 3))
    deg_s = np.array([1.2, -1.5, 0.9]) + rng.normal(0.0, 0.3, (n, 3))
    degs = direct_measurements(acc, deg_s)
    rads = direct_measurements(acc, np.radians(deg_s))
    said = (
        r"wx, wy, wz \(the gyro's gx, gy, gz\): the accelerometer's gravity direction turns "
        r"as the gyro says only"
    )
    est = make_estimator(method, make_formulation("direct"))
    with pytest.raises(ReadingUnitsError, match=said):
        est.run(t, degs)
    assert np.isfinite(est.run(t, rads).output[-1]).all()
    est.reset()
    for k in range(UNIT_CHECK_SAMPLES - 1):
        est.step(Measurement(float(t[k]), degs[k]))
    with pytest.raises(ReadingUnitsError, match=rf"^measurement at t=.* s: {said}"):
        est.step(Measurement(float(t[UNIT_CHECK_SAMPLES - 1]), degs[UNIT_CHECK_SAMPLES - 1]))


@pytest.mark.parametrize("method", ["mhe", "ekf"])
def test_gyros_in_degrees_per_second_stepped_one_by_one_are_refused(method) -> None:
    """A stream of raw readings whose gyros are in deg/s, handed to ``step`` sample by
    sample or to ``continue_run`` in blocks: a ReadingUnitsError at the sample that
    completes the first UNIT_CHECK_SAMPLES full readings over a second (their median),
    naming the gyro columns, and again at every later sample until a reset (named with its
    own time and the one that showed it); the samples
    before it are estimated. The same stream in rad/s runs through, and so does a
    1 kHz stream that turns at 6 rad/s for its first 0.12 s (a fast start, not deg/s)."""
    from continuum_mhe.estimators.reading_units import ReadingUnitsError
    from continuum_mhe.io.raw_units import UNIT_CHECK_SAMPLES
    from continuum_mhe.model.direct import direct_measurements

    n = UNIT_CHECK_SAMPLES + 20
    t = np.arange(n) * 0.02
    acc = np.array([[0.3, -0.2, 9.79]])
    rad_s = np.tile(direct_measurements(acc, np.radians([[30.0, 5.0, 0.0]])), (n, 1))
    rad_s[0] = np.nan  # a dropout first: the median is of full readings
    deg_s = rad_s.copy()
    deg_s[:, 3:] = np.degrees(deg_s[:, 3:])
    est = make_estimator(method, make_formulation("direct"))
    last = UNIT_CHECK_SAMPLES  # sample 0 has no reading: sample 100 is the 100th full one
    for k in range(last):
        est.step(Measurement(float(t[k]), deg_s[k]))
    said = (
        rf"^measurement at t={float(t[last])!r} s: wx, wy, wz \(the gyro's gx, gy, gz\): "
        r"gyro magnitude is about "
        rf"30\.4 \(median of the first {UNIT_CHECK_SAMPLES} full readings, 1\.98 s\), "
        r"implausible in rad/s \(above 5\): deg/s\? give rad/s"
    )
    with pytest.raises(ReadingUnitsError, match=said):
        est.step(Measurement(float(t[last]), deg_s[last]))
    later = (  # the next sample too, named with its own time and the one that showed it
        rf"^measurement at t={float(t[last + 1])!r} s: as found at t={float(t[last])!r} s, "
        r"wx, wy, wz \(the gyro's gx, gy, gz\): gyro magnitude is about 30\.4"
    )
    with pytest.raises(ReadingUnitsError, match=later):
        est.step(Measurement(float(t[last + 1]), deg_s[last + 1]))
    est.reset()
    first = est.continue_run(t[:60], deg_s[:60])  # not yet the first 100: stepped
    assert len(first.status) == 60
    with pytest.raises(
        UserError, match=r"wx, wy, wz \(the gyro's gx, gy, gz\): gyro magnitude is about 30\.4"
    ):
        est.continue_run(t[60:], deg_s[60:])
    est.reset()
    for k in range(n):
        assert est.step(Measurement(float(t[k]), rad_s[k])).status != "no-estimate" or k == 0
    est.reset()
    assert np.isfinite(est.continue_run(t, rad_s).output[5:]).all()
    fast = np.arange(1500) * 0.001  # 1 kHz: 6 rad/s for 0.12 s, then nearly at rest
    turn = np.where(fast[:, None] < 0.12, [[6.0, 0.0, 0.0]], [[0.01, 0.0, 0.0]])
    est.reset()
    est.continue_run(fast, direct_measurements(np.tile(acc, (1500, 1)), turn))


@pytest.mark.parametrize("method", ["mhe", "ekf"])
def test_refused_samples_do_not_count_toward_the_gyro_unit_check(method) -> None:
    """Samples the estimator refuses (a time not after the one before, handed to ``step``
    one by one, or inside a ``continue_run`` block, which is then refused whole) are not
    estimated, and their gyros do not enter the median of the unit check: rad/s readings,
    each followed by two repeats of its time whose gyros read in deg/s (a resent packet,
    refused), run through; so does the rad/s stream after a refused block in deg/s.
    Counted, the deg/s readings would make the median read as deg/s."""
    from continuum_mhe import SampleTimeError
    from continuum_mhe.io.raw_units import UNIT_CHECK_SAMPLES
    from continuum_mhe.model.direct import direct_measurements

    n = UNIT_CHECK_SAMPLES + 20
    t = np.arange(n) * 0.02
    acc = np.array([[0.3, -0.2, 9.79]])
    rad_s = np.tile(direct_measurements(acc, np.radians([[30.0, 5.0, 0.0]])), (n, 1))
    deg_s = rad_s.copy()
    deg_s[:, 3:] = np.degrees(deg_s[:, 3:])
    est = make_estimator(method, make_formulation("direct"))
    for k in range(n):
        est.step(Measurement(float(t[k]), rad_s[k]))
        for _ in range(2):
            with pytest.raises(SampleTimeError, match="later than the previous"):
                est.step(Measurement(float(t[k]), deg_s[k]))
    est.reset()
    back = t[:90].copy()
    back[-1] = back[-2]  # the block's last time repeats the one before: refused whole
    with pytest.raises(SampleTimeError, match="later than the previous"):
        est.continue_run(back, deg_s[:90])
    est.continue_run(t[:60], rad_s[:60])  # 1.18 s: with the refused block's, fewer than half
    assert np.isfinite(est.continue_run(t[60:], rad_s[60:]).output).all()


def test_each_raw_imus_first_full_reading_is_checked_by_step() -> None:
    """With one IMU silent from the start, the other's readings in m/s^2 are still
    refused at its first reading (the check does not wait for a sample with every IMU)."""
    from continuum_mhe.io.robot_file import read_robot

    est = make_estimator("ekf", make_formulation("direct", read_robot("two-section")))
    z = np.full(12, np.nan)
    z[:6] = [0.3, -0.2, 9.79, 0.01, 0.0, 0.02]  # IMU 1 in m/s^2, IMU 2 silent
    with pytest.raises(UserError, match=r"^measurement at t=0\.0 s: fx_1, fy_1, fz_1 have"):
        est.step(Measurement(0.0, z))


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (
            "make_formulation('direct', gyro_std='0.01')",
            "gyro_std must be a positive finite number",
        ),
        ("read_measurements(CSV, n_imus='2')", "n_imus must be a positive integer"),
        ("read_measurements(CSV, degrees='yes')", "degrees must be True or False"),
        ("load_input(CSV, None, make_formulation('bend'))", "options must be an InputOptions"),
        (
            "load_input(CSV, {'degrees': True}, make_formulation('bend'))",
            "options must be an InputOptions",
        ),
        ("open_input(CSV, InputOptions(), 'bend')", "formulation must be a Formulation"),
        ("write_estimates(None, SERIES)", "path must be a file path"),
        ("ImuPlacement(0, gyro_bias=('a', 'b', 'c'))", "IMU gyro_bias must be three finite rates"),
        ("ImuPlacement(0, gyro_bias=0.0)", "IMU gyro_bias must be three finite rates"),
        ("ImuPlacement(1.0)", "IMU section must be an integer"),
        ("RawImuSettings(mount_rpy=('a', 0, 0))", "mount_rpy must be three finite angles"),
        ("RawImuSettings(gyro_bias=0.1)", "gyro_bias must be three finite rates"),
        ("write_measurements(OUT, [0.0, 0.0], [[0.1, 0.1], [0.1, 0.1]])", "strictly increasing"),
        ("write_measurements(OUT, [0.0], [[0.1]])", "z has 1 columns, expected 2"),
        ("write_measurements(OUT, [0.0], [[0.1] * 4])", r"expected 2 \(roll, pitch\).*names="),
        ("write_truth(OUT, [0.0], [[0.0] * 18])", r"truth has 18 columns.*outputs=rec.outputs"),
        ("write_truth(OUT, [0.0], [[np.nan] * 5])", "refusing to write a non-finite value"),
        ("write_truth(OUT, [0.0], [[0.0] * 5] * 2)", "t has 1 samples and truth 2 rows"),
        ("write_measurements(OUT, [0.0, 1.0], [[0.1, 0.1]])", "t has 2 samples and z 1 rows"),
    ],
)
def test_library_calls_refuse_wrong_types_in_one_user_error(tmp_path, call, match) -> None:
    """Public library calls given a wrong type or an impossible value raise a UserError
    naming the argument, not a TypeError or AttributeError from inside; nothing is
    written."""
    import continuum_mhe.io as io
    from continuum_mhe.io.raw_imu import RawImuSettings
    from continuum_mhe.model.robot import ImuPlacement

    rec = simulate("paper3d", duration=0.2)
    csv = tmp_path / "m.csv"
    io.write_measurements(csv, rec.t, rec.z)
    names = {
        "CSV": csv, "OUT": tmp_path / "out.csv", "np": np, "make_formulation": make_formulation,
        "SERIES": make_estimator("ekf", make_formulation("bend")).run(rec.t, rec.z),
        **{name: getattr(io, name) for name in (
            "InputOptions", "load_input", "open_input", "read_measurements", "write_estimates",
            "write_measurements", "write_truth",
        )},
        "RawImuSettings": RawImuSettings, "ImuPlacement": ImuPlacement,
    }  # fmt: skip
    with pytest.raises(UserError, match=match):
        eval(call, names)
    assert not (tmp_path / "out.csv").exists()


def test_an_imu_section_given_as_a_numpy_integer_is_taken() -> None:
    """A section index that is a numpy integer (from an array) is an index like any
    other; a float is refused by its type."""
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section

    robot = Robot((Section(0.1), Section(0.1)), (ImuPlacement(0), ImuPlacement(np.int64(1))))
    assert robot.imus[1].section == 1 and type(robot.imus[1].section) is int


def test_masked_readings_are_dropouts() -> None:
    """A numpy masked array's masked readings are missing (NaN), in ``run`` and ``step``
    alike: ``numpy.asarray`` would keep the values under the mask (a disconnected
    sensor's noise, estimated as ``ok``)."""
    import numpy as np

    from continuum_mhe import Measurement, make_estimator, make_formulation, simulate

    rec = simulate("paper3d", duration=20.0, seed=0)
    z = rec.z.copy()
    z[100:140] = np.random.default_rng(1).normal(0.0, 0.035, (40, 2))
    masked = np.ma.masked_array(z, mask=False)
    masked[100:140] = np.ma.masked
    nan = z.copy()
    nan[100:140] = np.nan
    est = make_estimator("ekf", make_formulation("bend"))
    by_mask, by_nan = est.run(rec.t, masked), est.run(rec.t, nan)
    assert set(by_mask.status[100:140]) == {"dropout"}
    np.testing.assert_array_equal(by_mask.output, by_nan.output)
    est.reset()
    stepped = [est.step(Measurement(float(t), zi)) for t, zi in zip(rec.t, masked)]
    assert {str(e.status) for e in stepped[100:140]} == {"dropout"}


def test_a_formulation_switch_is_a_bool() -> None:
    import pytest

    from continuum_mhe import make_formulation
    from continuum_mhe.errors import UserError
    from continuum_mhe.io import read_robot

    robot = read_robot("two-section")
    for value in ("false", "no", None, 0):
        with pytest.raises(UserError, match="estimate_gyro_bias must be True or False"):
            make_formulation("direct", robot, estimate_gyro_bias=value)
    assert not any(
        s.startswith("bg")
        for s in make_formulation("direct", robot, estimate_gyro_bias=False).state_names
    )
    tendon = read_robot("tendon-two-section")  # an option that None leaves to the model
    with pytest.raises(UserError, match="must be True, False or None, got 'false'"):
        make_formulation("tendon", tendon, acceleration_from_force_rate="false")
    make_formulation("tendon", tendon, acceleration_from_force_rate=None)


def test_measurements_and_truth_on_a_unix_clock_round_trip(tmp_path) -> None:
    """Times of a Unix clock (1.7e9 s) keep their microseconds in the files the library
    writes (10 significant digits made every row 1700000000, which its reader refuses
    as a repeated time)."""
    import numpy as np

    from continuum_mhe import simulate
    from continuum_mhe.io import (
        read_measurements,
        read_state_table,
        write_measurements,
        write_truth,
    )

    rec = simulate("paper3d", duration=5.0)
    t = 1.7e9 + rec.t
    write_measurements(tmp_path / "m.csv", t, rec.z)
    write_truth(tmp_path / "truth.csv", t, rec.truth)
    np.testing.assert_allclose(read_measurements(tmp_path / "m.csv").t, t, rtol=0, atol=5e-7)
    np.testing.assert_allclose(read_state_table(tmp_path / "truth.csv").t, t, rtol=0, atol=5e-7)


def test_an_estimate_series_that_does_not_fit_is_refused(tmp_path) -> None:
    """A series whose status is short (the writer's zip cut the file to it), or whose
    times do not increase or statuses are unknown (the readers refuse such a file): a
    UserError, nothing written."""
    import dataclasses

    import numpy as np
    import pytest

    from continuum_mhe import make_estimator, make_formulation, simulate
    from continuum_mhe.errors import UserError
    from continuum_mhe.io import read_state_table, write_estimates

    rec = simulate("paper3d", duration=5.0)
    s = make_estimator("ekf", make_formulation("bend")).run(rec.t, rec.z)
    with pytest.raises(UserError, match=r"status has shape \(30,\), expected \(101,\)"):
        dataclasses.replace(s, status=s.status[:30])
    with pytest.raises(UserError, match=r"solve_ms has shape"):
        dataclasses.replace(s, solve_ms=s.solve_ms[:, None])
    out = tmp_path / "e.csv"
    glued = dataclasses.replace(s, t=np.concatenate([s.t[:50], s.t[:51]]))
    with pytest.raises(UserError, match="strictly increasing"):
        write_estimates(out, glued)
    with pytest.raises(UserError, match="status 'fine' is not one of"):  # refused when made
        dataclasses.replace(s, status=np.array(["fine"] * len(s.t)))
    assert not out.exists()
    write_estimates(out, s)
    assert len(read_state_table(out).t) == len(s.t)


def test_small_library_mistakes_are_user_errors() -> None:
    """A DataFrame whose columns are the readings in another order (numpy would drop the
    labels: every row ok, far off), or not the readings' names, a time beyond a float,
    float block starts, and a truth without rows to match: a UserError each, or nothing
    matched."""
    import numpy as np
    import pandas as pd
    import pytest

    from continuum_mhe import Measurement, make_estimator, make_formulation, simulate
    from continuum_mhe.errors import UserError
    from continuum_mhe.evaluation.metrics import match_rows

    rec = simulate("paper3d", duration=5.0)
    f = make_formulation("bend")
    est = make_estimator("ekf", f)
    table = pd.DataFrame(rec.z, columns=list(f.measurement_names))
    np.testing.assert_array_equal(est.run(rec.t, table).output, est.run(rec.t, rec.z).output)
    with pytest.raises(UserError, match="z's columns are pitch, roll"):
        est.run(rec.t, table[["pitch", "roll"]])
    # other names (one that says degrees), or another count: the formulation's names
    for bad in (["roll_deg", "pitch_deg"], ["roll", "pitch", "yaw"]):
        with pytest.raises(
            UserError, match=r"reads 2 readings a sample, roll, pitch: name them so"
        ):
            est.run(
                rec.t, pd.DataFrame(np.column_stack([rec.z, rec.z])[:, : len(bad)], columns=bad)
            )
    with pytest.raises(UserError, match=r"the measurement's labels are roll; .*: name them so"):
        est.step(Measurement(0.0, rec.z[0], labels=("roll",)))
    # raw IMU columns given to the model of raw IMUs: raw_measurements converts them
    direct = make_estimator("ekf", make_formulation("direct"))
    raw = pd.DataFrame(np.zeros((3, 6)), columns=["ax", "ay", "az", "gx", "gy", "gz"])
    with pytest.raises(UserError, match=r"are ax, ay, az, gx, gy, gz; .*inputs\.raw_measurements"):
        direct.run(np.arange(3) * 0.02, raw)
    # pandas' missing value in a nullable column is a dropout, as NaN is
    nullable = table.astype("Float64")
    nullable.iloc[3, 0] = pd.NA
    est.reset()
    assert list(est.run(rec.t, nullable).status[2:5]) == ["ok", "dropout", "ok"]
    missing = pd.Series([pd.NA, rec.z[0, 1]], index=["roll", "pitch"], dtype="Float64")
    assert np.isnan(Measurement(0.0, missing).z[0])  # step() takes it as run() does
    # a labelled Series to step(): the same check (its labels not dropped: no swap)
    est.reset()
    row = pd.Series({"pitch": rec.z[0, 1], "roll": rec.z[0, 0]})
    with pytest.raises(UserError, match="the measurement's labels are pitch, roll"):
        est.step(Measurement(0.0, row))
    first = est.step(Measurement(0.0, row[["roll", "pitch"]]))  # a start, unconfirmed
    assert first.status == "uncertain" and np.all(np.isfinite(first.output))
    est.reset()
    with pytest.raises(UserError, match="a number a float can hold"):
        Measurement(10**400, rec.z[0])
    est.reset()
    with pytest.raises(UserError, match="the blocks must cover"):
        est.continue_run(rec.t, rec.z, starts=[0.0, 50.0], block=50)
    i_est, i_truth = match_rows(rec.t, np.empty(0))
    assert len(i_est) == len(i_truth) == 0


def test_times_that_are_not_seconds_are_user_errors() -> None:
    """numpy datetimes for ``t`` (``run`` read them as nanoseconds, every row reset;
    ``step`` refuses them), and a recording whose median step is below 10 us (no IMU
    stream is that fast: a unit): a UserError each, in every estimator."""
    import numpy as np
    import pytest

    from continuum_mhe import make_estimator, make_formulation, simulate
    from continuum_mhe.errors import UserError

    rec = simulate("paper3d", duration=5.0)
    stamps = np.datetime64("2026-01-01") + (rec.t * 1e9).astype("timedelta64[ns]")
    for method in ("mhe", "ekf", "ukf"):
        est = make_estimator(method, make_formulation("bend"))
        with pytest.raises(UserError, match="numpy datetime or timedelta"):
            est.run(stamps, rec.z)
        for scale in (1e-200, 1e-6):  # 5e-202 and 5e-8 s a sample
            warned = r"^run: t advances by a median of .* s per sample .*; t must be in seconds$"
            with (
                pytest.warns(UserWarning, match=warned),
                pytest.raises(UserError, match="must be in seconds"),
            ):
                est.run(rec.t * scale, rec.z)


def test_step_and_continue_run_refuse_the_times_run_refuses() -> None:
    """Times 50 ns apart (``t`` in a unit far below seconds), which ``run`` refuses, are
    refused by ``continue_run`` and by ``step`` from the sample that ends the first
    ``TOO_FAST_STEPS`` (100) steps, each with run's message naming the method, and
    again at every later sample until ``reset()``; times in seconds step on, and so do
    times in seconds whose first rows are a burst 3 us apart (a serial buffer stamped
    as it is read), which ``run`` estimates too."""
    from continuum_mhe import Measurement, make_formulation, simulate
    from continuum_mhe.estimators.reading_units import ReadingUnitsError

    rec = simulate("paper3d", duration=6.0)
    t = rec.t * 1e-6  # 5e-8 s a sample
    said = (
        "t advances by a median of 5e-08 s per sample (2e+07 samples per second): "
        "t must be in seconds"
    )
    est = make_estimator("ekf", make_formulation("bend"))
    with pytest.raises(ReadingUnitsError, match=re.escape(f"run: {said}")):
        est.run(t, rec.z)
    est.reset()
    with pytest.raises(ReadingUnitsError, match=re.escape(f"continue_run: {said}")):
        est.continue_run(t, rec.z)
    with pytest.raises(ReadingUnitsError, match=re.escape(f"continue_run: {said}")):
        est.step(Measurement(t[0], rec.z[0]))  # again, until a reset
    est.reset()
    for i in range(100):
        assert est.step(Measurement(t[i], rec.z[i])).t == t[i]
    for i in (100, 101):
        with pytest.raises(ReadingUnitsError, match=re.escape(f"step: {said}")):
            est.step(Measurement(t[i], rec.z[i]))
    est.reset()
    assert est.step(Measurement(rec.t[0], rec.z[0])).t == rec.t[0]
    assert len(est.continue_run(rec.t[1:], rec.z[1:]).status) == len(rec.t) - 1
    burst = rec.t.copy()
    burst[1:4] = burst[0] + 3e-6 * np.arange(1, 4)  # rows 2 to 4: 3 us apart
    for how in ("step", "continue_run", "run"):
        est.reset()
        if how == "step":
            statuses = [est.step(Measurement(ti, zi)).status for ti, zi in zip(burst, rec.z)]
        else:
            statuses = list(getattr(est, how)(burst, rec.z).status)
        assert len(statuses) == len(burst), how  # every sample estimated, none refused


@pytest.mark.parametrize("how", ["step", "continue_run"])
def test_a_refused_first_time_that_is_not_finite_leaves_the_too_fast_check_on(how: str) -> None:
    """A garbled first line (t NaN), refused, then times in microseconds read as seconds:
    the check of times far too fast still refuses them from the sample that ends the
    first ``TOO_FAST_STEPS`` steps (a NaN kept in the check's times would compare false
    with every later one, and the check would never fill)."""
    from continuum_mhe import Measurement, SampleTimeError, make_formulation, simulate
    from continuum_mhe.estimators.reading_units import ReadingUnitsError

    rec = simulate("paper3d", duration=6.0)
    t = rec.t * 1e-6
    est = make_estimator("ekf", make_formulation("bend"))
    with pytest.raises(SampleTimeError, match="must be finite"):
        est.step(Measurement(float("nan"), rec.z[0]))
    with pytest.raises(ReadingUnitsError, match="t must be in seconds"):
        if how == "step":
            for ti, zi in zip(t, rec.z):
                est.step(Measurement(ti, zi))
        else:
            est.continue_run(t, rec.z)


def test_a_sample_refused_after_one_stamped_far_ahead_says_that_time_is_the_cause() -> None:
    """One sample stamped 40,000 s ahead (a wrong time) restarts the estimator after the
    gap; every true sample after it is then refused as late, and the refusal names
    both times' cases: reset() where the earlier time was the wrong one."""
    from continuum_mhe import Measurement, SampleTimeError, make_formulation, simulate

    rec = simulate("paper3d", duration=2.0)
    est = make_estimator("ekf", make_formulation("bend"))
    for i in range(20):
        est.step(Measurement(rec.t[i], rec.z[i]))
    est.step(Measurement(rec.t[20] + 4.0e4, rec.z[20]))
    for i in (21, 22):
        with pytest.raises(SampleTimeError, match=r"before it is 39999\.9 s later: if this "
                           r"sample's time is the wrong one.*until reset\(\)"):  # fmt: skip
            est.step(Measurement(rec.t[i], rec.z[i]))
    est.reset(keep_counts=True)
    assert est.step(Measurement(rec.t[23], rec.z[23])).t == rec.t[23]


def test_a_sample_stamped_far_behind_is_left_out_and_the_next_one_steps() -> None:
    """One sample whose own time is wrong (0 s in a stream at 1.4 s): its refusal says
    it can be left out, and the next true sample steps without a reset."""
    from continuum_mhe import Measurement, SampleTimeError, make_formulation, simulate

    rec = simulate("paper3d", duration=2.0)
    est = make_estimator("ekf", make_formulation("bend"))
    for i in range(30):
        est.step(Measurement(rec.t[i], rec.z[i]))
    with pytest.raises(SampleTimeError, match="leave it out and step on"):
        est.step(Measurement(0.0, rec.z[30]))
    assert est.step(Measurement(rec.t[31], rec.z[31])).t == rec.t[31]


def test_write_measurements_refuses_what_read_measurements_would(tmp_path) -> None:
    """An infinite reading (written empty: read back as a dropout), names given as one
    string (its letters became the columns) and no samples (a header alone): each a
    UserError, nothing written."""
    import numpy as np
    import pytest

    from continuum_mhe.errors import UserError
    from continuum_mhe.io import write_measurements

    out = tmp_path / "m.csv"
    t, z = np.array([0.0, 0.05]), np.array([[0.1, 0.2], [np.inf, 0.2]])
    for args, needle in (
        ((t, z), "row 2: roll is infinite"),
        ((t, np.zeros((2, 2)), "rp"), "names must be a sequence"),
        ((np.zeros(0), np.zeros((0, 2))), "no samples to write"),
    ):
        with pytest.raises(UserError, match=needle):
            write_measurements(out, *args)
        assert not out.exists()


def test_the_writers_refuse_times_their_readers_would_not_read_back(tmp_path, capsys) -> None:
    """Times written as one (1e15 + 0.25 k in ten significant digits: each ``1e+15``;
    1000.25 and 1000.2500001 s, to the microsecond: both ``1000.25``), which
    ``read_state_table`` refused as a time that does not increase, are refused by
    ``write_estimates``, ``write_truth``, ``write_measurements`` and the block writer
    that ``estimate`` uses (across two blocks too), naming the file and the row, and
    nothing is written; times of 0 and 1e300 s, and 1e14 + 0.25 k s, read back exactly."""
    from dataclasses import replace

    from continuum_mhe import make_formulation, simulate
    from continuum_mhe.errors import UserError
    from continuum_mhe.io import read_state_table, write_measurements, write_truth
    from continuum_mhe.io.estimate_csv import estimate_lines, write_estimates

    rec = simulate("paper3d", duration=0.25)
    series = make_estimator("ekf", make_formulation("bend")).run(rec.t, rec.z)
    n = len(rec.t)
    out = tmp_path / "e.csv"
    big = 1e15 + 0.25 * np.arange(n)
    hair = 1000.0 + rec.t
    hair[3] = hair[2] + 1e-7  # 1000.1000001 s, written 1000.1
    for t, said in (
        (big, "row 2: t = 1000000000000000.2 s is written 1e+15, not after the row before's 1e+15"),
        (hair, "row 4: t = 1000.1000001 s is written 1000.1, not after the row before's 1000.1"),
    ):
        for write, args in (
            (write_estimates, (replace(series, t=t),)),
            (write_truth, (t, rec.truth, rec.outputs)),
            (write_measurements, (t, rec.z, rec.measurement_names)),
            (estimate_lines, (t, series.output, series.std, None, series.status, series.solve_ms)),
        ):
            with pytest.raises(UserError, match=re.escape(f"{out}: {said}")):
                write(out, *args)  # type: ignore[operator]
            assert not out.exists()
    with pytest.raises(UserError, match=re.escape(f"{out}: row 1: t = 1000.1000001 s is written")):
        estimate_lines(  # the block after one that ended at 1000.1 s
            out, hair[3:], series.output[3:], series.std[3:], None, list(series.status[3:]),
            series.solve_ms[3:], after=hair[2],
        )  # fmt: skip
    for t in (np.array([0.0, 1e300]), 1e14 + 0.25 * np.arange(n)):
        write_estimates(out, replace(series.rows(slice(0, len(t))), t=t))
        assert read_state_table(out).t.tolist() == t.tolist()
    # estimate's blocks (1,024 rows each): the row named is the file's, not the block's
    long = simulate("paper3d", duration=150.0)
    t = 1000.0 + long.t
    t[2500] = t[2499] + 1e-7  # data row 2501, 0.1 us after the row before
    meas = tmp_path / "long.csv"
    rows = np.column_stack([t, long.z])
    header = ",".join(["t", *long.measurement_names])
    np.savetxt(meas, rows, delimiter=",", header=header, comments="", fmt="%.10f")
    from continuum_mhe.cli import main

    out = tmp_path / "long_est.csv"
    assert main(["estimate", str(meas), "--method", "ekf", "-o", str(out)]) == 2
    assert f"{out}: row 2501: t = 1124.9500001 s is written 1124.95" in capsys.readouterr().err
    assert not out.exists()


def test_a_state_tables_columns_by_name_and_the_reader_of_several_sections(tmp_path) -> None:
    """``StateTable.column`` and ``std_column`` read by name, an unknown one a KeyError
    listing the table's; ``read_states`` (one section) points a several-section file to
    ``read_state_table``."""
    from continuum_mhe.io import read_states, write_estimates
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section
    from continuum_mhe.simulation.scenarios import simulate_robot

    robot = Robot((Section(0.16, 3.0), Section(0.14, 3.0)), (ImuPlacement(0), ImuPlacement(1)))
    f = make_formulation("bend", robot)
    rec = simulate_robot("spatial", robot, duration=1.0, seed=0)
    series = make_estimator("ekf", f).run(rec.t, rec.z)
    path = tmp_path / "two.csv"
    write_estimates(path, series)
    table = read_state_table(path)
    np.testing.assert_allclose(table.column("theta_2"), series.column("theta_2"), rtol=1e-9)
    np.testing.assert_allclose(table.std_column("theta_2"), series.std_column("theta_2"), rtol=1e-9)
    with pytest.raises(KeyError, match="no column 'std_theta_2' .*theta_2"):
        table.column("std_theta_2")
    with pytest.raises(InputError, match="several sections .* read_state_table"):
        read_states(path)


def test_a_first_sample_without_a_finite_time_says_so() -> None:
    from continuum_mhe.errors import SampleTimeError

    est = make_estimator("ekf", make_formulation("bend"))
    with pytest.raises(SampleTimeError, match=r"t=nan s must be finite$"):
        est.step(Measurement(math.nan, np.zeros(2)))


def test_one_section_with_imus_along_it_simulates_the_one_section_scenarios(tmp_path) -> None:
    """A robot of one section with an IMU at its middle and one at its tip takes the
    one-section scenarios (each scenario sent it to the others' list), every IMU reading
    the section's bend as the model reads it (noise 0: to rounding); a two-section
    scenario names those it takes."""
    from continuum_mhe.errors import UserError
    from continuum_mhe.model.bend import BendFormulation
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section
    from continuum_mhe.simulation.scenarios import simulate_robot

    robot = Robot((Section(0.3),), (ImuPlacement(0, 0.5), ImuPlacement(0, 1.0)))
    rec = simulate_robot("paper3d", robot, duration=2.0, noise_deg=0.0)
    f = BendFormulation(robot=robot)
    theta, phi = rec.truth[:, 3], rec.truth[:, 4]
    x = np.column_stack([theta * np.cos(phi), theta * np.sin(phi), np.zeros((len(theta), 2))])
    model = np.asarray(f.functions.observe(x.T), dtype=float).reshape(f.nz, -1).T
    np.testing.assert_allclose(rec.z, model, rtol=0, atol=1e-12)
    assert rec.z.shape == (len(rec.t), 4) and np.ptp(rec.z[:, 0]) > 0.1
    with pytest.raises(UserError, match="for a robot of two or more sections.*choose from paper3d"):
        simulate_robot("spatial", robot)
    robot_file = tmp_path / "long.toml"
    robot_file.write_text(
        "[[section]]\nlength = 0.3\n[[imu]]\nsection = 1\nat = 0.5\n[[imu]]\nsection = 1\n"
    )
    out = tmp_path / "m.csv"
    argv = ["simulate", "planar-overbend", "--robot", str(robot_file), "-o", str(out)]
    assert main([*argv, "--duration", "1"]) == 0
    assert out.read_text().startswith("t,roll_1,pitch_1,roll_2,pitch_2\n")


def test_tensions_from_arrays_refuse_what_a_tensions_file_would() -> None:
    """``Tensions.from_rows`` (a tendon robot's tensions from arrays): arrays of other
    lengths or shapes, times that do not increase, a tension that is missing or
    negative: one UserError naming the stream and the problem, not an error from inside
    the derivatives."""
    from continuum_mhe.io.tensions import Tensions

    t = np.arange(10) * 0.02
    v = np.ones((10, 6))
    gap = v.copy()
    gap[3, 1] = np.nan
    cases = [
        ((t[:-1], v), r"^log: t has 9 times and the tensions 10 rows: they must match$"),
        ((t, v[:, 0]), r"^log: t must be \(n,\) s and the tensions \(n, k\) N"),
        ((t[::-1], v), r"^log: t must be finite and strictly increasing \(s\)$"),
        ((np.r_[t[:4], t[3:9]], v), r"^log: t must be finite and strictly increasing \(s\)$"),
        ((t[:0], v[:0]), r"^log: no tension rows$"),
        (("abc", v), r"^log: t and the tensions must be arrays of numbers"),
        ((t, gap), r"^log: row 3 \(t = 0.06 s\): tension_2 is nan: leave the row out"),
        ((t, -v), r"^log: row 0 \(t = 0 s\): tension_1 = -1 N is negative: a tendon cannot push"),
    ]
    for (times, values), match in cases:
        with pytest.raises(UserError, match=match):
            Tensions.from_rows("log", times, values)
    taken = Tensions.from_rows("log", list(t), v.tolist())  # lists are arrays too
    np.testing.assert_array_equal(taken.values, v)


def test_raw_readings_and_reset_name_a_wrong_argument() -> None:
    """``raw_readings`` given RobotSettings for its robot, and ``reset(keep_sensors=True)``
    without ``keep_counts`` (the sensors are kept within a recording): a UserError each."""
    from continuum_mhe import raw_readings, simulate_robot
    from continuum_mhe.io.robot_file import read_robot

    robot = read_robot("two-section")
    rec = simulate_robot("s-curve", robot, duration=0.2)
    with pytest.raises(UserError, match=r"^robot must be a Robot \(read_robot"):
        raw_readings(rec, RobotSettings())  # type: ignore[arg-type]
    with pytest.raises(UserError, match=r"^rec must be a Recording"):
        raw_readings(rec.z, robot)  # type: ignore[arg-type]
    est = make_estimator("ekf", make_formulation("bend"))
    with pytest.raises(UserError, match=r"keep_sensors=True\) needs keep_counts=True"):
        est.reset(keep_sensors=True)
    est.reset(keep_counts=True, keep_sensors=True)


def test_a_robot_built_in_code_gets_the_robot_files_slip_warnings() -> None:
    """``make_formulation`` on a robot built in code says what a robot file's reader
    would (IMUs out of base order or at one place, an ``at`` in metres, a ``mount_rpy``
    in radians, a ``gyro_bias`` in deg/s), once per robot, in 0-based terms; a clean
    robot and a robot file's (said by its reader) get none."""
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.model.robot import ImuPlacement, Robot, RobotWarning, Section

    # lengths no other test's robot has: a robot equal to one another test made, and
    # still holds, is said there (once per robot)
    two = (Section(0.1617), Section(0.1383))
    cases = [
        (
            (ImuPlacement(1), ImuPlacement(0)),
            r"imus\[1\] \(sections\[0\], at 1\) is nearer the base",
        ),
        ((ImuPlacement(0), ImuPlacement(0)), r"imus\[1\] is at the same place as imus\[0\]"),
        ((ImuPlacement(0, at=0.1617), ImuPlacement(1)), r"imus\[0\]\.at = 0\.1617 .* metres\?"),
        (
            (ImuPlacement(0), ImuPlacement(1, mount_rpy=(0.0, 1.5708, 0.0))),
            r"radians\? imus\[1\]\.mount_rpy",
        ),
        (
            (ImuPlacement(0, gyro_bias=(0.5, 0.0, 0.0)), ImuPlacement(1)),
            r"imus\[0\]\.gyro_bias .*deg/s\?",
        ),
    ]
    for imus, match in cases:
        robot = Robot(two, imus)
        with pytest.warns(RobotWarning, match=r"^robot: " + match):
            make_formulation("bend", robot)
        with warnings.catch_warnings():  # said once
            warnings.simplefilter("error")
            make_formulation("bend", robot)
    # a section of 3.17 m: centimetres read as metres?
    robot = Robot((Section(3.17), Section(0.1383)), (ImuPlacement(0), ImuPlacement(1)))
    with pytest.warns(RobotWarning, match=r"^robot: sections\[0\]: length 3\.17 m .* 0\.0317\)"):
        make_formulation("bend", robot)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        make_formulation("bend", Robot(two, (ImuPlacement(0), ImuPlacement(1))))
        make_formulation("bend", read_robot("two-section"))


def test_an_estimator_of_a_robot_built_with_a_mount_rpy_says_that_it_is_not_applied() -> None:
    """A robot built in code with an IMU's ``mount_rpy``, and readings handed to the
    estimator: the estimator takes them in each IMU's disk frame, so its first samples
    (``step``, ``run`` or ``continue_run``) get a warning, once per robot, naming the IMU;
    readings that came through the raw conversion (turned by ``mount_rpy``), before the
    estimator was made or after it (a control loop that converts each sample before it
    steps it), or from ``simulate_robot`` (in the disks' frames) get no warning."""
    from continuum_mhe.io import raw_measurements
    from continuum_mhe.model.robot import RobotWarning

    # lengths no other test's robot has: an equal robot would count as said
    mounted = Robot(
        (Section(0.1571), Section(0.1429)),
        (ImuPlacement(0), ImuPlacement(1, mount_rpy=(0.0, 0.0, 30.0))),
    )
    z = np.zeros(4)
    for k, how in enumerate(("step", "run", "continue_run")):
        if k:  # a robot not said of yet
            mounted = Robot((Section(0.1580 + k * 1e-4), Section(0.1420)), mounted.imus)
        formulation = make_formulation("bend", mounted)
        est = make_estimator("ekf", formulation)
        with pytest.warns(RobotWarning, match=r"^robot: the mount_rpy of IMU 2 is not applied"):
            if how == "step":
                est.step(Measurement(0.0, z))
            else:
                getattr(est, how)([0.0], [z])
        with warnings.catch_warnings():  # said once per robot
            warnings.simplefilter("error")
            make_estimator("ekf", formulation).step(Measurement(0.0, z))
    from continuum_mhe.estimators.kalman import ExtendedKalmanFilter

    built = Robot(  # an estimator built directly says it too, naming the caller's line
        (Section(0.1574), Section(0.1426)),
        (ImuPlacement(0), ImuPlacement(1, mount_rpy=(0.0, 0.0, 30.0))),
    )
    with pytest.warns(RobotWarning, match=r"IMU 2 is not applied") as said:
        ExtendedKalmanFilter(make_formulation("bend", built)).step(Measurement(0.0, z))
    assert said[0].filename == __file__
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        simulated = Robot(
            (Section(0.1572), Section(0.1428)),
            (ImuPlacement(0, mount_rpy=(0.0, 0.0, 20.0)), ImuPlacement(1)),
        )
        rec = simulate_robot("spatial", simulated, duration=0.5)
        make_estimator("ekf", make_formulation("bend", simulated)).run(rec.t, rec.z)
        converted = Robot(
            (Section(0.1573), Section(0.1427)),
            (ImuPlacement(0), ImuPlacement(1, mount_rpy=(0.0, 0.0, 40.0))),
        )
        acc = np.tile([0.0, 0.0, 9.81], (5, 2, 1))
        raw = raw_measurements(converted, np.arange(5) * 0.02, acc, np.zeros((5, 2, 3)))
        make_estimator("ekf", make_formulation("direct", converted)).run(np.arange(5) * 0.02, raw)
        in_loop = Robot(  # converted sample by sample after the estimator was made
            (Section(0.1575), Section(0.1425)),
            (ImuPlacement(0), ImuPlacement(1, mount_rpy=(0.0, 0.0, 40.0))),
        )
        est = make_estimator("ekf", make_formulation("direct", in_loop))
        for k in range(5):
            one = raw_measurements(
                in_loop, np.array([k * 0.02]), acc[k : k + 1], np.zeros((1, 2, 3))
            )
            est.step(Measurement(k * 0.02, one[0]))


@pytest.mark.parametrize(
    "make",
    [
        lambda big: Section(big),
        lambda big: Section(0.2, theta_max=big),
        lambda big: ImuPlacement(0, gyro_bias=(big, 0.0, 0.0)),
        lambda big: RobotSettings(length=big),
        lambda big: NoiseSettings(measurement_std=big),
        lambda big: MHESettings(tol=big),
    ],
    ids=["section-length", "theta-max", "gyro-bias", "robot-settings", "noise", "mhe-tol"],
)
def test_an_integer_beyond_a_floats_range_is_a_user_error(make) -> None:
    """10**400, a Python integer no float holds, is a UserError naming the argument (not
    an OverflowError from math.isfinite inside the check)."""
    with pytest.raises(UserError) as refused:
        make(10**400)
    assert "\n" not in str(refused.value)


def test_the_writers_refuse_what_their_readers_would_not_read_back(tmp_path) -> None:
    """write_measurements, write_truth and write_estimates wrote files their own readers
    refused (a column named twice or empty, a note over two lines, a truth out of time
    order or in degrees) or failed inside (a note that is no pair, outputs given as
    names): each is a UserError, and no file is written."""
    from continuum_mhe.io.estimate_csv import write_estimates, write_measurements, write_truth

    rec = simulate("paper3d", duration=1.0)
    series = make_estimator("ekf", make_formulation("bend")).run(rec.t, rec.z)
    out = tmp_path / "w.csv"
    refused = [
        (lambda: write_measurements(out, rec.t, rec.z, ["roll", "roll"]), "named twice"),
        (
            lambda: write_measurements(out, rec.t, rec.z, ["t", "pitch"]),
            "column 't' is named twice",
        ),
        (lambda: write_measurements(out, rec.t, rec.z, ["", "pitch"]), "column name ''"),
        (lambda: write_measurements(out, rec.t, rec.z, [1, 2]), "column name 1"),  # type: ignore[list-item]
        (lambda: write_truth(out, rec.t[::-1], rec.truth), "strictly increasing"),
        (lambda: write_truth(out, rec.t, rec.truth * [1, 1, 1, 57.3, 57.3]), "degrees?"),
        (
            lambda: write_truth(out, rec.t, rec.truth, ["x", "y", "z", "theta", "phi"]),
            "OutputSpecs",
        ),  # type: ignore[list-item]
        (lambda: write_estimates(out, series, [("options", "a\nb")]), "one-line strings"),
        (lambda: write_estimates(out, series, ["abc"]), "a (key, value) pair"),  # type: ignore[list-item]
    ]
    for write, said in refused:
        with pytest.raises(UserError, match=re.escape(said)):
            write()
        assert not out.exists()
    write_estimates(out, series, [("options", '{method = "ekf"}')])
    assert out.read_text().startswith('# options = {method = "ekf"}\n')


def test_more_library_mistakes_are_one_line_user_errors(tmp_path) -> None:
    """From a fuzzing of the library: run with t None (not "t has 1 samples"), with
    readings of bools or strings (not taken as 1.0 and 0.0, or parsed); load_input of a
    tilt file for the direct model (not an IndexError); raw_measurements given
    RobotSettings (not an AttributeError): each a UserError naming what to give."""
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import load_input, raw_measurements

    rec = simulate("paper3d", duration=1.0)
    est = make_estimator("ekf", make_formulation("bend"))
    for t, z, said in (
        (None, rec.z, "t is None: give the sample times"),
        (rec.t, rec.z > 0, "arrays of numbers (t (n,) s, z (n, m)); z holds bool values"),
        (rec.t, rec.z.astype(str), "arrays of numbers (t (n,) s, z (n, m)); z holds <U"),
    ):
        with pytest.raises(UserError, match=re.escape(said)):
            est.run(t, z)
    assert len(est.run(list(rec.t), [list(row) for row in rec.z]).t) == len(rec.t)
    tilt = tmp_path / "m.csv"
    assert main(["simulate", "paper3d", "--duration", "1", "-o", str(tilt)]) == 0
    with pytest.raises(UserError, match=r"tilt readings \(roll, pitch\) are read for the robot"):
        load_input(tilt, InputOptions(), make_formulation("direct"))
    with pytest.raises(UserError, match=r"^robot must be a Robot \(read_robot"):
        raw_measurements(RobotSettings(), rec.t, np.zeros((len(rec.t), 1, 3)))  # type: ignore[arg-type]


def test_a_tension_stream_refuses_what_is_no_tension_in_one_line() -> None:
    """TensionStream refuses 0, -1 or 2.5 tendons, a string for a time or for the
    tensions, bools and infinite tensions (not a failure inside numpy, nor NaN rates):
    each a UserError; a sample of numbers is taken."""
    from continuum_mhe.io.tensions import TensionStream

    for n in (0, -1, 2.5):
        with pytest.raises(UserError, match="n_tendons must be a positive integer"):
            TensionStream(n_tendons=n)  # type: ignore[arg-type]
    stream = TensionStream(n_tendons=2)
    for text in ("abc", ["1", "2"], [True, False]):  # text, even of numbers; bools
        with pytest.raises(UserError, match="tensions that are not numbers"):
            stream.push(0.05, text)  # type: ignore[arg-type]
    with pytest.raises(UserError, match=r"tension_2 = inf: give NaN for a tension that is missing"):
        stream.push(0.05, [1.0, np.inf])
    with pytest.raises(UserError, match="a sample's time must be a number of seconds"):
        stream.push("0.07", [1.0, 2.0])  # type: ignore[arg-type]
    assert stream.push(0.1, [1.0, 2.0]) == []  # (its derivatives need two more)


def test_a_robot_or_formulation_given_before_the_name_is_told_the_order() -> None:
    """``make_formulation(robot)`` and ``make_estimator(formulation, "ekf")``, the
    arguments swapped: one line each saying which comes first, not the name check's
    message with the object's whole repr."""
    robot = Robot((Section(0.2),), (ImuPlacement(0),))
    with pytest.raises(UserError, match=r"^make_formulation takes the formulation's name first"):
        make_formulation(robot)  # type: ignore[arg-type]
    formulation = make_formulation("bend", robot)
    with pytest.raises(UserError, match=r"^make_estimator takes the method first") as info:
        make_estimator(formulation, "ekf")  # type: ignore[arg-type]
    assert len(str(info.value)) < 200


def test_formulation_options_of_no_number_are_one_user_error_naming_them() -> None:
    """The raw-IMU model's and the tendon model's number options given None, a string, or
    a value whose square (a variance) a float cannot hold: one UserError naming the
    option, not a TypeError or OverflowError from inside the model; a numpy integer seed
    is a seed (the same recording as the int)."""
    from dataclasses import replace

    from continuum_mhe import make_formulation, simulate
    from continuum_mhe.errors import UserError
    from continuum_mhe.io.robot_file import read_robot

    direct = make_formulation("direct", read_robot("two-section"))
    for value in (None, "0.01", 1e300, 1e-300):
        with pytest.raises(UserError, match=r"^gyro_std must be a positive finite number"):
            replace(direct, gyro_std=value)
    tendon = make_formulation("tendon", read_robot("tendon-two-section"))
    for value in (None, "1.0"):
        with pytest.raises(UserError, match=r"^tension_std must be a number, got"):
            replace(tendon, tension_std=value)
    with pytest.raises(UserError, match=r"^force_accel_psd must be a number or None, got"):
        replace(tendon, force_accel_psd="1.0")
    assert np.array_equal(simulate("paper3d", duration=1.0, seed=np.int64(3)).z,
                          simulate("paper3d", duration=1.0, seed=3).z)  # fmt: skip


def test_a_start_prior_wider_than_the_robots_reach_is_taken_as_its_reach() -> None:
    """``initial_bend_std`` 100 rad, wider than any bend the robot can make: every
    estimator starts from a prior of the bend bound's width (so the unscented filter's
    sigma points do not wrap the angles); one whose square no float holds is refused
    naming it."""
    from continuum_mhe import NoiseSettings, make_formulation, simulate
    from continuum_mhe.errors import UserError

    rec = simulate("paper3d", duration=3.0, seed=1)
    f = make_formulation("bend", None, NoiseSettings(initial_bend_std=100.0))
    _, P = f.start_prior(rec.z[0])
    np.testing.assert_allclose(np.sqrt(np.diag(P))[:2], f.robot.sections[0].theta_max)
    for method in ("ekf", "ukf", "mhe"):
        series = make_estimator(method, f).run(rec.t, rec.z)
        assert np.mean(series.status == "ok") > 0.9, (method, series.diagnostics)
    with pytest.raises(UserError, match=r"^initial_bend_std 1e\+300 is too large"):
        NoiseSettings(initial_bend_std=1e300)


def test_step_refuses_what_run_refuses_and_run_names_a_ragged_list() -> None:
    """``step`` with readings given as bools or text is refused as ``run`` refuses them
    (not estimated from 1.0 and 0.0 rad), and ``run`` given rows of different lengths
    says so in a UserError (not numpy's inhomogeneous-shape ValueError)."""
    from continuum_mhe import Measurement, make_formulation, simulate
    from continuum_mhe.errors import UserError

    est = make_estimator("ekf", make_formulation("bend"))
    for z in ([True, False], ["0.1", "0.2"]):
        with pytest.raises(UserError, match="measurement z must be numbers"):
            est.step(Measurement(0.0, z))
    rec = simulate("paper3d", duration=1.0)
    with pytest.raises(UserError, match=r"^z must be an array .*its rows differ in length"):
        est.run(rec.t[:3], [[0.1, 0.1], [0.1], [0.1, 0.1]])


def test_readings_that_mix_bools_with_numbers_are_refused_as_bools_are() -> None:
    """A bool among numbers (``[True, 0.1]``, which numpy reads as ``[1.0, 0.1]``) is
    refused by ``step``, ``run``, ``continue_run`` and ``TensionStream.push`` with the
    UserError that readings of bools alone get, not estimated from 1.0."""
    from continuum_mhe import Measurement, make_formulation, simulate
    from continuum_mhe.errors import UserError
    from continuum_mhe.io.tensions import TensionStream

    est = make_estimator("ekf", make_formulation("bend"))
    for z in ([True, False], [True, 0.1], np.array([0.1, np.True_], dtype=object)):
        with pytest.raises(UserError, match=r"^measurement z must be numbers, got"):
            est.step(Measurement(0.0, z))
    rec = simulate("paper3d", duration=0.5)
    said = "t and z must be arrays of numbers (t (n,) s, z (n, m)); z holds bool values"
    for z in (rec.z > 0, [[True, *row[1:]] for row in rec.z.tolist()]):
        for call in (est.run, est.continue_run):
            with pytest.raises(UserError, match=re.escape(said)):
                call(rec.t, z)
    t_said = said.replace("z holds", "t holds")
    with pytest.raises(UserError, match=re.escape(t_said)):
        est.run([True, *rec.t[1:].tolist()], rec.z)
    stream = TensionStream(n_tendons=2)
    for tensions in ([True, False], [True, 1.0]):
        with pytest.raises(UserError, match="tensions that are not numbers"):
            stream.push(0.05, tensions)  # type: ignore[arg-type]
    assert stream.push(0.05, [1.0, 2.0]) == []  # numbers alone are taken


def test_a_method_array_is_refused_and_robot_settings_write_as_a_robot_file(tmp_path) -> None:
    """``make_estimator`` given an array of method names (a loop's mistake) is one
    UserError naming the methods, not numpy's ambiguous truth value; ``write_robot``
    takes a one-section ``RobotSettings`` as ``make_formulation`` does, and the file
    reads back as that robot."""
    from continuum_mhe import RobotSettings, make_formulation
    from continuum_mhe.errors import UserError
    from continuum_mhe.io import read_robot, write_robot
    from continuum_mhe.model.formulations import as_robot

    with pytest.raises(UserError, match=r"^method must be one of"):
        make_estimator(np.array(["ekf", "ukf"]), make_formulation("bend"))  # type: ignore[arg-type]
    assert type(make_estimator(np.array(["ekf", "ukf"])[0], make_formulation("bend"))).__name__ == (
        "ExtendedKalmanFilter"
    )
    settings = RobotSettings(length=0.3, mounting="z-down")
    write_robot(tmp_path / "one.toml", settings)
    assert read_robot(tmp_path / "one.toml") == as_robot(settings)


def test_an_estimate_series_built_by_hand_is_checked_in_user_errors() -> None:
    """An ``EstimateSeries`` made in code with outputs of the wrong shape or a status
    that is none of the statuses: one UserError naming it (not a ValueError, or a
    KeyError when its statuses are counted); outputs given as a list are taken."""
    from continuum_mhe import EstimateSeries
    from continuum_mhe.errors import UserError

    t, ok = np.arange(3.0), np.tile([0.01, 0.02, 0.19, 0.1, 0.5], (3, 1))
    status = np.array(["ok"] * 3)
    with pytest.raises(UserError, match=r"^output has shape \(3, 3\), expected \(3, 5\)"):
        EstimateSeries("ekf", t, ok[:, :3], status, np.zeros(3))
    with pytest.raises(UserError, match=r"^status 'bogus' is not one of ok, "):
        EstimateSeries("ekf", t, ok, np.array(["bogus"] * 3), np.zeros(3))
    series = EstimateSeries("ekf", t, ok.tolist(), status, np.zeros(3))  # type: ignore[arg-type]
    assert [str(s.value) for s in series.statuses()] == ["ok"] * 3


def test_an_estimate_series_built_by_hand_takes_its_times_as_an_array() -> None:
    """An ``EstimateSeries`` made in code with its times as a list is one whose rows a
    mask selects (the times an array, not a TypeError from indexing the list), and times
    given as a column (n, 1) or as text are one UserError naming ``t``."""
    from continuum_mhe import EstimateSeries
    from continuum_mhe.errors import UserError

    t, out = [0.0, 0.5, 1.0], np.tile([0.01, 0.02, 0.19, 0.1, 0.5], (3, 1))
    status = np.array(["ok"] * 3)
    series = EstimateSeries("ekf", t, out, status, [0.1, 0.1, 0.1])  # type: ignore[arg-type]
    assert series.t.dtype == np.float64 and series.solve_ms.dtype == np.float64
    late = series.rows(series.t >= 0.5)
    assert late.t.tolist() == [0.5, 1.0]
    with pytest.raises(UserError, match=r"^t has shape \(3, 1\), expected \(n,\)"):
        EstimateSeries("ekf", np.array(t)[:, None], out, status, np.zeros(3))
    with pytest.raises(UserError, match=r"^t must be an array of numbers"):
        EstimateSeries("ekf", ["0", "a", "1"], out, status, np.zeros(3))  # type: ignore[arg-type]


def test_write_robot_refuses_a_robot_of_another_type_naming_it(tmp_path) -> None:
    """``write_robot`` given a robot file's name (what ``read_robot`` takes) or None is
    one UserError naming the argument, and writes no file: not an AttributeError from
    inside the writer, nor the default robot's file for None."""
    from continuum_mhe.errors import UserError
    from continuum_mhe.io import write_robot

    for robot in ("two-section", None):
        path = tmp_path / "robot.toml"
        with pytest.raises(UserError, match=r"^write_robot robot must be a Robot or RobotSettings"):
            write_robot(path, robot)  # type: ignore[arg-type]
        assert not path.exists()
