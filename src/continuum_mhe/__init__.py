"""continuum-mhe: shape and tip estimation of continuum robots from IMUs on the robot.

Public surface::

    from continuum_mhe import (Robot, Section, ImuPlacement, NoiseSettings, MHESettings,
                               RecoverySettings, make_formulation, make_estimator,
                               simulate, simulate_robot, Measurement, backbone_points,
                               calibrate_robot)
    from continuum_mhe.io import read_measurements, write_estimates

The names are imported on first use (PEP 562), so that ``continuum-mhe --help`` and
``--version`` stay light.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

#: public name -> the module that defines it
_EXPORTS: dict[str, str] = {
    "METHODS": "continuum_mhe.estimators",
    "Diagnostics": "continuum_mhe.estimators",
    "Estimate": "continuum_mhe.estimators",
    "EstimateSeries": "continuum_mhe.estimators",
    "Estimator": "continuum_mhe.estimators",
    "ExtendedKalmanFilter": "continuum_mhe.estimators",
    "Measurement": "continuum_mhe.estimators",
    "MovingHorizonEstimator": "continuum_mhe.estimators",
    "UnscentedKalmanFilter": "continuum_mhe.estimators",
    "make_estimator": "continuum_mhe.estimators",
    "CalibrationNote": "continuum_mhe.calibration.robot_calibration",
    "CalibrationWarning": "continuum_mhe.calibration.robot_calibration",
    "RobotCalibration": "continuum_mhe.calibration.robot_calibration",
    "calibrate_robot": "continuum_mhe.calibration.robot_calibration",
    "FieldError": "continuum_mhe.errors",
    "InputError": "continuum_mhe.errors",
    "NotANumberError": "continuum_mhe.errors",
    "SampleTimeError": "continuum_mhe.errors",
    "TimeUnitError": "continuum_mhe.errors",
    "UnobservableShapeWarning": "continuum_mhe.errors",
    "UserError": "continuum_mhe.errors",
    "ReadingUnitsError": "continuum_mhe.estimators.reading_units",
    "BackendFallbackWarning": "continuum_mhe.estimators.fast.window_functions",
    "FigureWarning": "continuum_mhe.evaluation.estimate_figure",
    "UnsolvedBackboneError": "continuum_mhe.evaluation.estimate_tables",
    "TruthCoverageWarning": "continuum_mhe.evaluation.metrics",
    "MissingExtraError": "continuum_mhe.extras",
    "DropoutWarning": "continuum_mhe.io.csv_files",
    "UnitWarning": "continuum_mhe.io.csv_files",
    "TimeStepWarning": "continuum_mhe.io.csv_files",
    "TimesWrittenAsOneError": "continuum_mhe.io.estimate_csv",
    "TopicClockWarning": "continuum_mhe.io.imu_topics",
    "TopicOrderWarning": "continuum_mhe.io.imu_topics",
    "MountingError": "continuum_mhe.io.input_options",
    "MountingWarning": "continuum_mhe.io.input_options",
    "OptionWarning": "continuum_mhe.io.input_options",
    "RobotFileWarning": "continuum_mhe.io.robot_file",
    "FrameWarning": "continuum_mhe.io.robot_logs",
    "TensionsWarning": "continuum_mhe.io.tensions",
    "CutLineWarning": "continuum_mhe.io.text_rows",
    "RobotWarning": "continuum_mhe.model.robot",
    "Metrics": "continuum_mhe.evaluation.metrics",
    "compute_metrics": "continuum_mhe.evaluation.metrics",
    "DirectFormulation": "continuum_mhe.model.direct",
    "BendFormulation": "continuum_mhe.model.bend",
    "Formulation": "continuum_mhe.model.formulations",
    "PaperFormulation": "continuum_mhe.model.paper",
    "make_formulation": "continuum_mhe.model.registry",
    "backbone_points": "continuum_mhe.model.pcc",
    "ImuPlacement": "continuum_mhe.model.robot",
    "Robot": "continuum_mhe.model.robot",
    "Section": "continuum_mhe.model.robot",
    "Backbone": "continuum_mhe.model.robot",
    "Tendon": "continuum_mhe.model.robot",
    "Status": "continuum_mhe.results",
    "MHESettings": "continuum_mhe.settings",
    "NoiseSettings": "continuum_mhe.settings",
    "RecoverySettings": "continuum_mhe.settings",
    "RobotSettings": "continuum_mhe.settings",
    "Recording": "continuum_mhe.simulation.scenarios",
    "simulate": "continuum_mhe.simulation.scenarios",
    "simulate_robot": "continuum_mhe.simulation.scenarios",
    "raw_readings": "continuum_mhe.simulation.raw_readings",
    "ViewNote": "continuum_mhe.viewer.view",
    "ViewWarning": "continuum_mhe.viewer.view",
}

__all__ = sorted([*_EXPORTS, "__version__"])


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'continuum_mhe' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # later lookups skip this function
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_EXPORTS])


if TYPE_CHECKING:  # for type checkers and IDEs: the same names, imported eagerly
    from continuum_mhe.calibration.robot_calibration import (
        CalibrationNote,
        CalibrationWarning,
        RobotCalibration,
        calibrate_robot,
    )
    from continuum_mhe.errors import (
        FieldError,
        InputError,
        NotANumberError,
        SampleTimeError,
        TimeUnitError,
        UnobservableShapeWarning,
        UserError,
    )
    from continuum_mhe.estimators import (
        METHODS,
        Diagnostics,
        Estimate,
        EstimateSeries,
        Estimator,
        ExtendedKalmanFilter,
        Measurement,
        MovingHorizonEstimator,
        UnscentedKalmanFilter,
        make_estimator,
    )
    from continuum_mhe.estimators.fast.window_functions import BackendFallbackWarning
    from continuum_mhe.estimators.reading_units import ReadingUnitsError
    from continuum_mhe.evaluation.estimate_figure import FigureWarning
    from continuum_mhe.evaluation.estimate_tables import UnsolvedBackboneError
    from continuum_mhe.evaluation.metrics import Metrics, TruthCoverageWarning, compute_metrics
    from continuum_mhe.extras import MissingExtraError
    from continuum_mhe.io.csv_files import DropoutWarning, TimeStepWarning, UnitWarning
    from continuum_mhe.io.estimate_csv import TimesWrittenAsOneError
    from continuum_mhe.io.imu_topics import TopicClockWarning, TopicOrderWarning
    from continuum_mhe.io.input_options import MountingError, MountingWarning, OptionWarning
    from continuum_mhe.io.robot_file import RobotFileWarning
    from continuum_mhe.io.robot_logs import FrameWarning
    from continuum_mhe.io.tensions import TensionsWarning
    from continuum_mhe.io.text_rows import CutLineWarning
    from continuum_mhe.model.bend import BendFormulation
    from continuum_mhe.model.direct import DirectFormulation
    from continuum_mhe.model.formulations import Formulation
    from continuum_mhe.model.paper import PaperFormulation
    from continuum_mhe.model.pcc import backbone_points
    from continuum_mhe.model.registry import make_formulation
    from continuum_mhe.model.robot import (
        Backbone,
        ImuPlacement,
        Robot,
        RobotWarning,
        Section,
        Tendon,
    )
    from continuum_mhe.results import Status
    from continuum_mhe.settings import (
        MHESettings,
        NoiseSettings,
        RecoverySettings,
        RobotSettings,
    )
    from continuum_mhe.simulation.raw_readings import raw_readings
    from continuum_mhe.simulation.scenarios import Recording, simulate, simulate_robot
    from continuum_mhe.viewer.view import ViewNote, ViewWarning
