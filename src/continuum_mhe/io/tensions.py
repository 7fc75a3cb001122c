"""Tendon tensions files: ``t,tension_1,...,tension_k`` (s, N), in the robot file's
``[[tendon]]`` order, at any rate.

The tensions at a measurement's time are interpolated linearly between the file's
rows; their rates are the central differences of the file's rows, and their second
derivatives the central differences of those rates, both interpolated the same way
(what the gyros see of the tendons' pull, and the IMUs' own acceleration that the
accelerometers read). A tensions file
must cover the recording: a measurement before its first row or after its last is an
error, as are a negative or non-finite tension, a wrong number of tension columns and
times that do not increase.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from continuum_mhe.io.csv_files import FloatArray
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.text_rows import InputError, iter_samples, open_rows
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.tendon import TendonFormulation


@dataclass(frozen=True)
class Tensions:
    """A tensions file read whole.

    Attributes:
        name: the file as shown in messages.
        t: (n,) s, strictly increasing.
        values: (n, k) N, non-negative.
        rates: (n, k) N/s, central differences (one-sided at the ends; zero with one
            row).
        accelerations: (n, k) N/s^2, the rates' central differences (the same way).
    """

    name: str
    t: FloatArray
    values: FloatArray
    rates: FloatArray
    accelerations: FloatArray

    def at(self, t: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``(tensions, rates, accelerations)`` at ``t`` s, linear between rows; an
        :class:`InputError` outside the file's times."""
        if not self.t[0] <= t <= self.t[-1]:
            raise InputError(
                f"{self.name}: the tensions cover t = {self.t[0]:g} to {self.t[-1]:g} s, "
                f"but a measurement is at t = {t:g} s: the tensions must cover the "
                "recording; nothing written"
            )
        return tuple(  # type: ignore[return-value]
            np.array([np.interp(t, self.t, v) for v in a.T])
            for a in (self.values, self.rates, self.accelerations)
        )


def read_tensions(path: str | os.PathLike[str], n_tendons: int) -> Tensions:
    """Read and check a tensions file for a robot with ``n_tendons`` tendons."""
    names = [f"tension_{i}" for i in range(1, n_tendons + 1)]
    with open_rows(path) as rows:
        name = rows.name
        found = [c for c in rows.header if c != "t"]
        if "t" not in rows.header or found != names:
            raise InputError(
                f"{name}: expected the columns t,{','.join(names)} (one per [[tendon]] of "
                f"the robot file, in its order), got {','.join(rows.header)}"
            )
        data = list(iter_samples(rows, ["t", *names]))
    if not data:
        raise InputError(f"{name}: no tension rows")
    t = np.array([d[1] for d in data], dtype=float)
    values = np.array([d[2] for d in data], dtype=float).reshape(len(t), n_tendons)
    neg = np.argwhere(values < 0)
    if len(neg):
        i, j = neg[0]
        raise InputError(
            f"{name}: line {data[i][0]}: tension_{j + 1} = {values[i, j]:g} N is negative: "
            "a tendon cannot push (a slack tendon's tension is 0)"
        )
    rates = np.zeros_like(values)
    accelerations = np.zeros_like(values)
    if len(t) > 1:
        rates = np.asarray(np.gradient(values, t, axis=0), dtype=float)
        accelerations = np.asarray(np.gradient(rates, t, axis=0), dtype=float)
    return Tensions(name, t, values, rates, accelerations)


def tendon_formulation_for(base: Formulation, options: InputOptions) -> TendonFormulation:
    """The tendon formulation of ``base``'s robot, with ``base``'s IMU model (tilt, or
    raw with ``direct``) and noise."""
    if options.estimate_accel_bias or options.own_acceleration:
        flag = "--estimate-accel-bias" if options.estimate_accel_bias else "--own-acceleration"
        raise InputError(f"{flag} is not available for a tendon robot (a [backbone] robot file)")
    direct = base.name == "direct"
    return TendonFormulation(
        robot=base.robot,
        noise=base.noise,
        imu_model="direct" if direct else "tilt",
        gyro_std=options.gyro_std,
        estimate_gyro_bias=direct and options.estimate_gyro_bias is not False,
    )
