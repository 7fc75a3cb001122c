"""Reading and writing recordings, estimates, robot files and robot logs.

The common readers and writers, importable from here::

    from continuum_mhe.io import (read_measurements, read_raw_imus, read_states,
                                  read_robot, read_imu_log, write_estimates,
                                  write_measurements, write_truth, write_robot,
                                  InputError)

Any input ``estimate`` reads (tilt or raw CSV, ROS bag, MCAP) as measurements for an
estimator, with the command line's input options: :func:`open_input` (a stream) or
:func:`load_input` (whole), :class:`InputOptions` (:mod:`continuum_mhe.io.inputs`).

Every reader raises :class:`InputError` (a ``ValueError``) with one line naming the
file and line. Names are imported on first use.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

_EXPORTS: dict[str, str] = {
    "InputError": "continuum_mhe.errors",
    "MeasurementTable": "continuum_mhe.io.csv_files",
    "StateTable": "continuum_mhe.io.state_tables",
    "atomic_writer": "continuum_mhe.io.output_files",
    "read_measurements": "continuum_mhe.io.csv_files",
    "read_state_table": "continuum_mhe.io.state_tables",
    "read_states": "continuum_mhe.io.state_tables",
    "write_estimates": "continuum_mhe.io.estimate_csv",
    "write_measurements": "continuum_mhe.io.estimate_csv",
    "write_truth": "continuum_mhe.io.estimate_csv",
    "InputOptions": "continuum_mhe.io.input_options",
    "InputDescription": "continuum_mhe.io.inputs",
    "EstimateInput": "continuum_mhe.io.inputs",
    "MeasurementStream": "continuum_mhe.io.inputs",
    "load_input": "continuum_mhe.io.inputs",
    "open_input": "continuum_mhe.io.inputs",
    "RawImuSettings": "continuum_mhe.io.raw_imu",
    "read_raw_imu": "continuum_mhe.io.raw_imu",
    "raw_measurements": "continuum_mhe.io.inputs",
    "read_raw_imus": "continuum_mhe.io.raw_imu",
    "read_robot": "continuum_mhe.io.robot_file",
    "write_robot": "continuum_mhe.io.robot_file",
    "TensionStream": "continuum_mhe.io.tensions",
    "read_tensions": "continuum_mhe.io.tensions",
    "read_imu_log": "continuum_mhe.io.robot_logs",
    "read_imu_topics": "continuum_mhe.io.imu_topics",
    "read_estimates_mcap": "continuum_mhe.io.mcap_estimates",
    "write_estimates_mcap": "continuum_mhe.io.mcap_estimates",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'continuum_mhe.io' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_EXPORTS])


if TYPE_CHECKING:
    from continuum_mhe.errors import InputError
    from continuum_mhe.io.csv_files import MeasurementTable, read_measurements
    from continuum_mhe.io.estimate_csv import write_estimates, write_measurements, write_truth
    from continuum_mhe.io.imu_topics import read_imu_topics
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import (
        EstimateInput,
        InputDescription,
        MeasurementStream,
        load_input,
        open_input,
        raw_measurements,
    )
    from continuum_mhe.io.mcap_estimates import read_estimates_mcap, write_estimates_mcap
    from continuum_mhe.io.output_files import atomic_writer
    from continuum_mhe.io.raw_imu import RawImuSettings, read_raw_imu, read_raw_imus
    from continuum_mhe.io.robot_file import read_robot, write_robot
    from continuum_mhe.io.robot_logs import read_imu_log
    from continuum_mhe.io.state_tables import StateTable, read_state_table, read_states
    from continuum_mhe.io.tensions import TensionStream, read_tensions
