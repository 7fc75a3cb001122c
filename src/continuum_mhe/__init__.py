"""continuum-mhe: shape and tip estimation of continuum robots from IMUs on the robot.

Public surface::

    from continuum_mhe import (RobotSettings, NoiseSettings, MHESettings,
                               make_formulation, make_estimator, simulate, Measurement)
"""

# isort: off
from continuum_mhe import numba_cache  # noqa: F401  (first: a cache folder before numba)

# isort: on
from continuum_mhe.estimators import (
    METHODS,
    Estimate,
    EstimateSeries,
    Estimator,
    ExtendedKalmanFilter,
    Measurement,
    MovingHorizonEstimator,
    UnscentedKalmanFilter,
    make_estimator,
)
from continuum_mhe.metrics import Metrics, compute_metrics
from continuum_mhe.model.direct import DirectFormulation
from continuum_mhe.model.formulations import BendFormulation, Formulation, PaperFormulation
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.settings import MHESettings, NoiseSettings, RobotSettings
from continuum_mhe.simulation.scenarios import Recording, simulate

__version__ = "0.1.0"

__all__ = [
    "METHODS",
    "BendFormulation",
    "DirectFormulation",
    "Estimate",
    "EstimateSeries",
    "Estimator",
    "ExtendedKalmanFilter",
    "Formulation",
    "ImuPlacement",
    "MHESettings",
    "Measurement",
    "Metrics",
    "MovingHorizonEstimator",
    "NoiseSettings",
    "PaperFormulation",
    "Recording",
    "Robot",
    "RobotSettings",
    "Section",
    "UnscentedKalmanFilter",
    "__version__",
    "compute_metrics",
    "make_estimator",
    "make_formulation",
    "simulate",
]
