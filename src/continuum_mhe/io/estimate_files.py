"""Estimate files of either format, for the commands that read them back (``evaluate``,
``plot``, ``view``): an estimate CSV, or an estimate MCAP (``estimate -o EST.mcap``)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from continuum_mhe.errors import InputError
from continuum_mhe.io.csv_files import tilt_columns
from continuum_mhe.io.mcap_estimates import read_estimate_table_mcap
from continuum_mhe.io.raw_imu import is_raw_header
from continuum_mhe.io.state_tables import (
    STATE_HEADER_HINT,
    TRUE_SUFFIX,
    StateTable,
    read_state_table,
    truth_named,
)
from continuum_mhe.io.text_rows import open_rows
from continuum_mhe.model.descriptions import TIP_COLUMNS


def is_mcap(path: str) -> bool:
    """Whether ``path`` names an MCAP file (by its suffix, as ``estimate -o`` writes it)."""
    return Path(path).suffix.lower() == ".mcap"


def read_estimates(
    path: str, then: str, required: Sequence[str] = (), truth_as_estimate: bool = True
) -> StateTable:
    """The estimate CSV or MCAP ``path``, with at least ``required`` columns (a CSV's);
    a measurement CSV (tilt or raw, no tip columns) is a one-line error saying to
    estimate it first and then run ``then`` (``view EST.csv``: the command on the
    estimates). A recording with its truth beside the measurements (``x_true``...) is
    read as that truth, unless not ``truth_as_estimate``: then it is a one-line error
    saying that it holds no estimate columns, to estimate it first or give it as
    ``--truth`` (``plot``, which would draw the truth as an estimate)."""
    if is_mcap(path):
        return read_estimate_table_mcap(path)
    with open_rows(
        path, STATE_HEADER_HINT
    ) as rows:  # the header first: a measurement file's rows may
        header = [h for h in rows.header if h != "t"]  # hold dropouts (empty, nan)
        written = [rows.as_written(h) for h in header]
    # a recording with its truth beside the measurements (x_true...) is read as that truth
    named = truth_named(header, TIP_COLUMNS)
    if named != header and not truth_as_estimate:
        truths = [w for h, w in zip(header, written) if h.endswith(TRUE_SUFFIX)]
        raise InputError(
            f"{path}: a recording with truth columns ({', '.join(truths)}) but no estimate "
            f"columns ({', '.join(TIP_COLUMNS)}, status): run continuum-mhe estimate {path} "
            f"-o EST.csv first, then continuum-mhe {then} --truth {path}"
        )
    header = named
    tilt = [tilt_columns(n)[0] for n in (1, 2)]  # roll, roll_1
    if not set(TIP_COLUMNS) <= set(header) and (
        is_raw_header(header) or any(c in header for c in tilt)
    ):
        raise InputError(
            f"{path}: a measurement file (columns {', '.join(written)}), not an estimate: "
            f"run continuum-mhe estimate {path} -o EST.csv first, then continuum-mhe {then}"
        )
    return read_state_table(path, required)


def require_an_estimate(path: str, table: StateTable) -> None:
    """A one-line :class:`InputError` where no row of the estimate file ``path`` holds an
    estimate (every row ``no-estimate``, or its tip empty): nothing to draw."""
    values = table.values[:, [i for i, c in enumerate(table.names) if c in TIP_COLUMNS]]
    if values.shape[1] == 0:  # no tip columns: the estimate's every value
        values = table.values
    held = (table.status != "no-estimate") & np.all(np.isfinite(values), axis=1)
    if values.shape[1] == 0 or not held.any():
        raise InputError(f"{path}: no row has an estimate (every one is no-estimate or empty)")
