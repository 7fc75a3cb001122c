"""The Rerun recording of backbone estimates (:class:`BackboneView`); see the package
doc for its entities."""

from __future__ import annotations

import contextlib
import errno
import math
import os
import shutil
import sys
import time
import uuid
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from subprocess import Popen
from typing import Any

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import InputError
from continuum_mhe.extras import install_hint, require
from continuum_mhe.io.output_files import temporary_beside
from continuum_mhe.model.descriptions import (
    TIP_COLUMNS,
    TIP_FORCE_COLUMNS,
    OutputSpec,
    imu_twist_names,
    robot_outputs,
    section_bends,
    section_end_indices,
)
from continuum_mhe.model.robot import Robot
from continuum_mhe.results import Estimate, Status
from continuum_mhe.viewer.geometry import (
    BackboneGeometry,
    TendonShapes,
    backbone_geometry,
    joined_through_ends,
    with_imu_twists,
)
from continuum_mhe.viewer.sink import ViewerSink, start_web_viewer, stop_web_viewer

INSTALL_HINT = install_hint("view")
APPLICATION_ID = "continuum-mhe"
#: colours of successive sections (RGB), repeated beyond four sections
SECTION_COLOURS = ((31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40))
TRUTH_COLOUR = (150, 150, 150)
TRAIL_COLOUR = (227, 119, 194)
FORCE_COLOUR = (23, 190, 207)
#: A tip force's arrow is this share of the robot's length per the backbone's force
#: scale ``E I / L^2`` (N; ``I`` the round backbone's second moment of area, ``L`` the
#: robot's length): a load that bends the robot visibly draws an arrow of a fraction of
#: its size (0.27 m for 0.29 N on the shipped 0.4 m tendon robot).
FORCE_ARROW_SHARE = 0.15
#: free bytes below which a failed .rrd write is put down to a full disk, and below
#: which no .rrd is begun (Rerun's file writer can hang on a disk that fills while it
#: writes a recording's first bytes)
DISK_NEARLY_FULL = 1 << 20
#: How long closing a .rrd waits for Rerun to write out what it holds, s: its file
#: writer can wait forever on a full disk; one that has not finished by then has failed
FLUSH_TIMEOUT_S = 20.0
#: The wait is made of slices this long, s: after each one unfinished, a writer whose
#: file did not grow over it while its disk has less than DISK_NEARLY_FULL free is
#: taken as stuck at once
FLUSH_SLICE_S = 0.5


class ViewWarning(UserWarning):
    """What a view draws that may not be what was meant: a backbone the mechanics model
    holds no equilibrium for, joined through its section ends, or one that misses the
    estimated tip (another robot's or recording's tensions)."""


class ViewNote(UserWarning):
    """How a view took its inputs, where it is not what a reader would assume: a tendon
    robot's tips drawn alone without its tensions, tensions taken on a robot log's
    clock. The command line says it as a note (``continuum-mhe: note: ...``)."""


def free_bytes(folder: Path) -> int:
    """The bytes this process can still write in ``folder``'s file system: the blocks
    free to every user, and for root the reserved ones too; :data:`DISK_NEARLY_FULL`
    where the file system cannot say."""
    try:
        if not hasattr(os, "statvfs"):  # Windows: what every user may write
            return shutil.disk_usage(folder).free
        st = os.statvfs(folder)
    except OSError:
        return DISK_NEARLY_FULL
    blocks = st.f_bfree if os.geteuid() == 0 else st.f_bavail
    return int(blocks * st.f_frsize)


def _leave_unclosed(rr: Any, rec: Any) -> None:
    """Leave the recording ``rec``, whose file writer is stuck (a full disk), as it is
    to the process's end: closing it, freeing it (``RecordingStream.__del__``) or
    Rerun's shutdown at exit would each wait for that writer, so the process would
    never end. It gets a reference that is never released, and Rerun's exit handler
    (``rr``'s) is taken off."""
    import ctypes

    ctypes.pythonapi.Py_IncRef(ctypes.py_object(rec))  # the interpreter's end frees it not
    rr.unregister_shutdown()


def require_rerun() -> Any:
    """The ``rerun`` module, or one line naming the install command (exit 2).

    Rerun's own log lines (its Rust side's, read from ``RUST_LOG`` when it is first
    imported) are off unless ``RUST_LOG`` is set: a file it cannot write reaches the
    user as this package's one line, naming the file and why. The variable is set for
    that import only (a viewer it starts, or another Rust library, sees the user's)."""
    if "rerun" in sys.modules or "RUST_LOG" in os.environ:
        return require("rerun", "view", "the 3D view", package="rerun-sdk")
    os.environ["RUST_LOG"] = "off"
    try:
        return require("rerun", "view", "the 3D view", package="rerun-sdk")
    finally:
        os.environ.pop("RUST_LOG", None)


def nanoseconds(t: Any) -> Any:
    """Times ``t`` (s, a number or an array) as Rerun's durations, rounded to the
    nanosecond (Rerun truncates seconds given as floats: 2.05 s would be 2049999999 ns)."""
    ns = np.rint(np.asarray(t, dtype=float) * 1e9).astype(np.int64)
    return ns.astype("timedelta64[ns]") if ns.ndim else np.timedelta64(int(ns), "ns")


def force_arrow_scale(robot: Robot) -> float | None:
    """Metres of a tip force's arrow per newton: :data:`FORCE_ARROW_SHARE` of the robot's
    length ``L`` per ``E I / L^2`` N, the backbone's force scale (``I = pi r^4 / 4``);
    None for a robot without a backbone (no tip force)."""
    b = robot.backbone
    if b is None:
        return None
    length = robot.length
    return FORCE_ARROW_SHARE * length / (b.bending_stiffness / length**2)


def force_label(force: FloatArray) -> str:
    """A tip force's arrow label: its magnitude in N."""
    return f"{float(np.linalg.norm(force)):.3f} N"


class BackboneView:
    """A Rerun recording of backbone estimates (see the module doc for its entities).

    ``log_estimate`` is the per-estimate hook of ``live``; ``log_rows`` replays arrays.
    Call ``close`` at the end (it finishes the .rrd file, or stops the web viewer).
    A tendon robot's shapes come from its mechanics model (``tendon``): from each
    estimate's state live, and from the rows' tip force and the tensions in a replay
    (without the tensions a replay draws the tip alone).
    """

    def __init__(
        self,
        robot: Robot,
        outputs: Sequence[OutputSpec],
        sink: ViewerSink,
        *,
        trail_s: float = 10.0,
        points_per_section: int = 16,
        name: str = "continuum-mhe",
        max_hz: float | None = None,
        tendon: TendonShapes | None = None,
    ) -> None:
        if not (math.isfinite(trail_s) and trail_s > 0):
            raise InputError(f"--trail must be positive seconds, got {trail_s}")
        if max_hz is not None and not (math.isfinite(max_hz) and max_hz >= 0):
            raise InputError(f"--view-hz must be 0 (every estimate) or positive, got {max_hz}")
        if points_per_section < 1:
            raise InputError(f"--points must be at least 1, got {points_per_section}")
        self.rr = rr = require_rerun()
        self.robot = robot
        self.outputs = tuple(outputs)
        self.sink = sink
        self.points_per_section = points_per_section
        self.tendon = tendon
        self._web: Popen[bytes] | None = None
        self._tmp: Path | None = None
        #: whether Rerun's writer did not finish within FLUSH_TIMEOUT_S: its recording
        #: is then left as it is (:func:`_leave_unclosed`)
        self._stuck = False
        self._closed = False  # close() was called: a second call does nothing
        #: the estimates logged one by one (``log_estimate``)
        self.estimates = 0
        self._prev_tip: dict[str, FloatArray | None] = {"estimate": None, "truth": None}
        self._status = ""
        self._min_step = 1.0 / max_hz if max_hz else 0.0
        self._drawn_t: float | None = None
        #: the last estimate left undrawn by ``max_hz`` since the last one drawn
        self._undrawn: Estimate | None = None
        #: the rows of the estimate and of the truth sent (``log_rows``, ``log_truth``)
        #: whose loads the mechanics model holds no equilibrium under: their backbones
        #: drawn through their section ends, as ``plot`` draws them, without IMU frames
        self.joined_through_ends = {"estimate": 0, "truth": 0}
        #: a tendon robot's replay: the largest distance (m) between the end of the
        #: mechanics model's backbone at a row's tip force and that row's own tip (a
        #: robot file or tensions other than the estimate's draw a backbone that misses)
        self.model_tip_off = 0.0
        #: the angles a shape is drawn from (a truth's backbone needs them): the bends,
        #: and a tendon robot's twists; not an output beyond the shape (``imu_twist``)
        self._shape_angles = {o.name for o in robot_outputs(robot) if o.unit == "rad"}
        names = [o.name for o in self.outputs]
        #: the tip's ``x, y, z`` among the outputs
        self._tip_columns = [names.index(c) for c in TIP_COLUMNS]
        #: the tip force's ``fx, fy, fz`` among the outputs (a tendon robot's), else None
        self._force_columns = (
            [names.index(c) for c in TIP_FORCE_COLUMNS]
            if all(c in names for c in TIP_FORCE_COLUMNS)
            else None
        )
        #: each IMU's twist ``imu_twist_i`` among the outputs (``--imu-twist``), else None
        twists = imu_twist_names(robot.n_imus)
        self._twist_columns = (
            [names.index(c) for c in twists] if all(c in names for c in twists) else None
        )
        #: m of arrow per N of tip force (:data:`FORCE_ARROW_SHARE`); None without a
        #: backbone
        self._arrow_per_newton = force_arrow_scale(robot)
        #: output columns by unit, in ``outputs`` order
        self._units = {
            u: [j for j, o in enumerate(self.outputs) if o.unit == u]
            for u in sorted({o.unit for o in self.outputs})
        }
        self.rec = rr.RecordingStream(APPLICATION_ID, recording_id=str(uuid.uuid4()))
        self.rec.send_recording_name(name)
        blueprint = self._blueprint(trail_s)
        self._open(blueprint)
        self._log_static()

    # setup
    def _blueprint(self, trail_s: float) -> Any:
        import rerun.blueprint as rrb

        trail = rrb.VisibleTimeRanges(
            rrb.VisibleTimeRange(
                "t",
                start=rrb.TimeRangeBoundary.cursor_relative(seconds=-trail_s),
                end=rrb.TimeRangeBoundary.cursor_relative(),
            )
        )
        units = sorted({o.unit for o in self.outputs})
        return rrb.Blueprint(
            rrb.Horizontal(
                rrb.Spatial3DView(
                    origin="/world",
                    name="backbone",
                    overrides={f"/world/{w}/tip_trail": trail for w in ("estimate", "truth")},
                ),
                rrb.Vertical(
                    *(
                        rrb.TimeSeriesView(origin=f"/outputs/{u}", name=f"outputs ({u})")
                        for u in units
                    ),
                    rrb.TextLogView(origin="/status", name="status"),
                ),
                column_shares=[3, 2],
            ),
            collapse_panels=False,
        )

    def _open(self, blueprint: Any) -> None:
        sink = self.sink
        if sink.kind == "save":
            assert sink.path is not None  # checked by ViewerSink
            folder = sink.path.parent if str(sink.path.parent) else Path(".")
            if not folder.is_dir():
                raise InputError(f"{sink.path}: folder {folder} does not exist")
            free = free_bytes(folder)
            if free < DISK_NEARLY_FULL:
                raise InputError(
                    f"{sink.path}: cannot write (its disk has {free // 1024} KiB free, "
                    f"a view needs {DISK_NEARLY_FULL >> 20} MiB) (nothing written)"
                )
            # written beside the target and renamed at close: never a half-written .rrd
            self._tmp = temporary_beside(sink.path)
            try:
                self.rec.save(self._tmp, default_blueprint=blueprint)
            except RuntimeError as exc:  # Rerun's file errors
                self._tmp.unlink(missing_ok=True)
                raise InputError(f"{sink.path}: cannot write ({exc}) (nothing written)") from None
        elif sink.kind == "spawn":
            if why := sink.display_missing():  # the commands say so first, in their options
                raise InputError(
                    f"Rerun's native viewer needs a display ({why}); "
                    "use ViewerSink('web') or ViewerSink('save', Path('FILE.rrd'))"
                )
            self.rec.spawn(port=sink.grpc_port, default_blueprint=blueprint)
        else:
            self._web = start_web_viewer(sink)
            self.rec.connect_grpc(sink.grpc_url, default_blueprint=blueprint)

    def _log_static(self) -> None:
        rr, rec = self.rr, self.rec
        up = rr.ViewCoordinates.RIGHT_HAND_Z_UP
        if self.robot.mounting == "z-down":
            up = rr.ViewCoordinates.RIGHT_HAND_Z_DOWN
        rec.log("world", up, static=True)
        rec.log("world/base", rr.TransformAxes3D(0.15 * self.robot.length), static=True)
        for unit, cols in self._units.items():
            names = [self.outputs[j].name for j in cols]
            rec.log(f"outputs/{unit}", rr.SeriesLines(names=names), static=True)

    # logging
    def _bends(self, values: FloatArray) -> FloatArray:
        return np.stack([section_bends(self.outputs, row) for row in values])

    def _style(self, who: str) -> tuple[list[tuple[int, int, int]], list[str] | None]:
        n = self.robot.n_sections
        if who == "truth":
            return [TRUTH_COLOUR] * n, None
        colours = [SECTION_COLOURS[k % len(SECTION_COLOURS)] for k in range(n)]
        return colours, [f"section {k + 1}" for k in range(n)] if n > 1 else None

    def _log_status(self, status: str) -> None:
        if status != self._status:
            level = "INFO" if status == Status.OK else "WARN"
            self.rec.log("status", self.rr.TextLog(f"status: {status}", level=level))
            self._status = status

    def log_estimate(self, est: Estimate) -> None:
        """The live hook: log one estimate (its ``output`` in ``outputs`` order), one
        entity at a time (``log_rows`` sends a whole recording as columns)."""
        rr, rec = self.rr, self.rec
        self.estimates += 1
        rec.set_time("t", duration=nanoseconds(est.t))
        changed = str(est.status) != self._status
        self._log_status(str(est.status))
        out = est.output
        if out is None or est.status == Status.NO_ESTIMATE or not np.all(np.isfinite(out)):
            rec.log("world/estimate", rr.Clear(recursive=True))
            self._prev_tip["estimate"] = None
            self._drawn_t = None
            return
        if (
            not changed
            and self._drawn_t is not None
            and 0 <= est.t - self._drawn_t < self._min_step
        ):
            self._undrawn = est  # drawn at close if no later one is
            return  # max_hz: drawn often enough (status changes and gaps always are)
        self._draw_estimate(est, out)

    def _draw_estimate(self, est: Estimate, out: FloatArray) -> None:
        """Draw the estimate ``est`` with its outputs ``out`` (its time set)."""
        rr, rec, size = self.rr, self.rec, self.robot.length
        self._undrawn = None
        self._drawn_t = float(est.t)
        if self.tendon is not None and est.state is not None:
            geom = self.tendon.from_states(est.state[None, :])
        else:
            geom = backbone_geometry(self.robot, self._bends(out[None, :]), self.points_per_section)
            if self._twist_columns is not None:
                geom = with_imu_twists(self.robot, geom, out[None, self._twist_columns])
        colours, labels = self._style("estimate")
        rec.log(
            "world/estimate/backbone",
            rr.LineStrips3D(list(geom.sections[0]), radii=0.01 * size, colors=colours,
                            labels=labels),
        )  # fmt: skip
        # the tip is the row's own x, y, z: a tendon robot's drawing's finer steps end
        # within a millimetre of it, and the paper formulation's are states of their own
        tip = out[self._tip_columns]
        rec.log("world/estimate/tip", rr.Points3D([tip], radii=0.015 * size))
        prev = self._prev_tip["estimate"]
        if prev is not None:
            rec.log(
                "world/estimate/tip_trail",
                rr.LineStrips3D([[prev, tip]], radii=0.004 * size, colors=[TRAIL_COLOUR]),
            )
        self._prev_tip["estimate"] = tip
        if self._force_columns is not None and self._arrow_per_newton is not None:
            force = out[self._force_columns]
            rec.log(
                "world/estimate/tip_force",
                rr.Arrows3D(origins=[tip], vectors=[force * self._arrow_per_newton],
                            radii=0.006 * size, colors=[FORCE_COLOUR],
                            labels=[force_label(force)]),
            )  # fmt: skip
        for i in range(self.robot.n_imus):
            rec.log(
                f"world/estimate/imu_{i + 1}",
                rr.Transform3D(translation=geom.imu_position[0, i],
                               mat3x3=geom.imu_rotation[0, i]),
                rr.TransformAxes3D(0.1 * size),
            )  # fmt: skip
        for unit, cols in self._units.items():
            rec.log(f"outputs/{unit}", rr.Scalars(out[cols]))

    def _send_shapes(self, who: str, t: FloatArray, geom: BackboneGeometry | None,
                     tips: FloatArray, joined: NDArray[np.bool_],
                     forces: FloatArray | None = None) -> None:  # fmt: skip
        """Columns of one recording's shapes at times ``t`` (n,): the backbone and IMU
        frames of ``geom`` (if any), the ``tips`` (n, 3) m and their trail, and the tip
        ``forces`` (n, 3) N as arrows from the tips (if any); ``joined[k]`` is True where
        sample ``k`` continues the trail from sample ``k - 1``."""
        rr, rec, size = self.rr, self.rec, self.robot.length
        n, n_sec = len(t), self.robot.n_sections
        colours, labels = self._style(who)

        def send(entity: str, times: FloatArray, columns: Any) -> None:
            rec.send_columns(entity, indexes=[rr.TimeColumn("t", duration=nanoseconds(times))],
                             columns=columns)  # fmt: skip

        if geom is not None:
            send(
                f"world/{who}/backbone", t,
                rr.LineStrips3D.columns(
                    strips=list(geom.sections.reshape(n * n_sec, -1, 3)),
                    radii=[0.01 * size] * (n * n_sec),
                    colors=colours * n,
                    labels=None if labels is None else labels * n,
                ).partition([n_sec] * n),
            )  # fmt: skip
        send(f"world/{who}/tip", t,
             rr.Points3D.columns(positions=tips, radii=[0.015 * size] * n))  # fmt: skip
        k = np.flatnonzero(joined)
        if len(k):
            segments = np.stack([tips[k - 1], tips[k]], axis=1)
            send(
                f"world/{who}/tip_trail", t[k],
                rr.LineStrips3D.columns(
                    strips=list(segments), radii=[0.004 * size] * len(k),
                    colors=[TRUTH_COLOUR if who == "truth" else TRAIL_COLOUR] * len(k),
                ),
            )  # fmt: skip
        if forces is not None and self._arrow_per_newton is not None:
            send(
                f"world/{who}/tip_force", t,
                rr.Arrows3D.columns(
                    origins=tips, vectors=forces * self._arrow_per_newton,
                    radii=[0.006 * size] * n,
                    colors=[TRUTH_COLOUR if who == "truth" else FORCE_COLOUR] * n,
                    labels=[force_label(f) for f in forces],
                ),
            )  # fmt: skip
        if geom is None:
            return
        # a row without an equilibrium: its backbone joined through its section ends
        # (:func:`joined_through_ends`), no IMU frame
        posed = np.all(np.isfinite(geom.imu_position.reshape(n, -1)), axis=1)
        self.joined_through_ends[who] += int(n - posed.sum())
        if who == "truth":
            return
        for i in range(self.robot.n_imus):
            if posed.any():
                send(
                    f"world/{who}/imu_{i + 1}", t[posed],
                    [*rr.Transform3D.columns(translation=geom.imu_position[posed, i],
                                             mat3x3=geom.imu_rotation[posed, i]),
                     *rr.TransformAxes3D.columns(axis_length=[0.1 * size] * int(posed.sum()))],
                )  # fmt: skip
            for tk in t[~posed]:  # the frame of the row before is not this row's
                rec.set_time("t", duration=nanoseconds(tk))
                rec.log(f"world/{who}/imu_{i + 1}", rr.Clear(recursive=False))

    def log_rows(self, t: FloatArray, values: FloatArray, status: Sequence[str]) -> None:
        """Send a recording's estimates as columns: ``t`` (n,) s, ``values`` (n,
        n_outputs) in ``outputs`` order (m, rad; NaN where there is no estimate),
        ``status`` (n,; ``""`` for rows of a file without statuses: none is logged).
        Draws what ``log_estimate`` draws row by row."""
        t = np.asarray(t, dtype=float)
        values = np.asarray(values, dtype=float).reshape(len(t), len(self.outputs))
        has = np.all(np.isfinite(values), axis=1) & (np.asarray(status) != "no-estimate")
        for k in range(len(t)):  # status changes and clears: few rows, one at a time
            if str(status[k]) != self._status or not has[k]:
                self.rec.set_time("t", duration=nanoseconds(t[k]))
                self._log_status(str(status[k]))
                if not has[k]:
                    self.rec.log("world/estimate", self.rr.Clear(recursive=True))
        if not has.any():
            return
        geom, tips = self._row_shapes(t[has], values[has], [o.name for o in self.outputs])
        if self.tendon is not None and geom is not None:
            off = np.linalg.norm(geom.tip - tips, axis=1)
            if np.isfinite(off).any():
                self.model_tip_off = max(self.model_tip_off, float(np.nanmax(off)))
        joined = (has & np.concatenate([[False], has[:-1]]))[has]
        forces = None if self._force_columns is None else values[has][:, self._force_columns]
        self._send_shapes("estimate", t[has], geom, tips, joined, forces)
        n = int(has.sum())
        for unit, cols in self._units.items():
            self.rec.send_columns(
                f"outputs/{unit}",
                indexes=[self.rr.TimeColumn("t", duration=nanoseconds(t[has]))],
                columns=self.rr.Scalars.columns(scalars=values[has][:, cols].ravel()).partition(
                    [len(cols)] * n
                ),
            )
        self._prev_tip["estimate"] = tips[-1] if has[-1] else None

    def _row_shapes(
        self, t: FloatArray, values: FloatArray, names: Sequence[str]
    ) -> tuple[BackboneGeometry | None, FloatArray]:
        """The shapes and tips (n, 3) m of rows ``values`` (columns ``names``) at ``t``:
        the PCC model's from their bends, or a tendon robot's from their tip force and
        the tensions, times their tension gains where they have them (None without the
        tensions or the force; the tips are the rows' ``x, y, z``)."""
        col = {c: i for i, c in enumerate(names)}
        if self.tendon is None:
            ordered = values[:, [col.get(o.name, col["x"]) for o in self.outputs]]
            geom = backbone_geometry(self.robot, self._bends(ordered), self.points_per_section)
            if self._twist_columns is not None and all(
                self.outputs[j].name in col for j in self._twist_columns
            ):  # an estimate's IMU twists (a truth has none)
                geom = with_imu_twists(self.robot, geom, ordered[:, self._twist_columns])
            return geom, values[:, [col[c] for c in TIP_COLUMNS]]  # the rows' own tips
        tips = values[:, [col[c] for c in TIP_COLUMNS]]
        if self.tendon.tensions is None or not all(c in col for c in TIP_FORCE_COLUMNS):
            return None, tips
        forces = values[:, [col[c] for c in TIP_FORCE_COLUMNS]]
        geom, unsolved = self.tendon.solved_forces(t, forces, names, values)
        if not unsolved:
            return geom, tips
        rows = ~np.all(np.isfinite(geom.sections.reshape(len(t), -1)), axis=1)
        n_sec = self.robot.n_sections
        ends = np.repeat(tips[rows][:, None, :], n_sec, axis=1)  # the tip, where no end
        for k in range(1, n_sec + 1):
            named = self._section_end_names(k)
            if named and all(c in col for c in named):
                ends[:, k - 1] = values[rows][:, [col[c] for c in named]]
            elif k < n_sec:  # a truth without its section ends: one line base to tip
                ends[:, k - 1] = tips[rows] * k / n_sec
        warnings.warn(
            f"{len(unsolved)} of the backbones drawn joined through their section ends: the "
            f"mechanics model holds no equilibrium under their loads; the first: {unsolved[0]}",
            ViewWarning,
            stacklevel=3,
        )
        return joined_through_ends(geom, rows, ends), tips

    def _section_end_names(self, k: int) -> list[str]:
        """The names of section ``k``'s end position among the outputs (``x_k, y_k,
        z_k``; none where the outputs have none: one constant-curvature section)."""
        return [self.outputs[i].name for i in section_end_indices(self.outputs, k)]

    def _draws_shape_from(self, name: str) -> bool:
        """Whether a truth's column ``name`` is one the backbone is drawn from: a bend
        angle of the model's outputs, the tip force or a tension gain (a tendon robot's
        equilibrium)."""
        angle = any(o.name == name and o.name in self._shape_angles for o in self.outputs)
        return angle or name in TIP_FORCE_COLUMNS or name.startswith("tension_gain_")

    def log_truth(self, t: FloatArray, values: FloatArray, names: Sequence[str]) -> bool:
        """Send a truth recording: ``values`` (n, len(names)), columns named as in a truth
        CSV. The tip and its trail are its ``x, y, z``; each section end ``x_k, y_k,
        z_k`` it has is a point (``world/truth/section_ends``); the backbone is drawn by
        the PCC model from its ``theta, phi`` columns, where it has them all (on rod
        data the PCC curve through the true bends, not the rod itself). Returns whether
        the backbone was drawn. A column without a value (every row NaN) is taken as
        absent, and a row with a gap (NaN) in a column drawn is left out: the view holds
        the truth drawn before it (where no row has every column the backbone is drawn
        from, the tip and section ends alone are drawn)."""
        t = np.asarray(t, dtype=float)
        values = np.asarray(values, dtype=float)
        some = [j for j in range(len(names)) if np.isfinite(values[:, j]).any()]
        names, values = [names[j] for j in some], values[:, some]
        sections = range(1, self.robot.n_sections + 1)
        end_columns = {c for k in sections for c in self._section_end_names(k)}
        points = [j for j, c in enumerate(names) if c in TIP_COLUMNS or c in end_columns]
        whole = np.all(np.isfinite(values[:, points]), axis=1)
        shape = [j for j, c in enumerate(names) if j not in points and self._draws_shape_from(c)]
        with_shape = whole & np.all(np.isfinite(values[:, shape]), axis=1)
        if with_shape.any():
            whole = with_shape
        else:  # no row has every column the backbone is drawn from: the points alone
            kept = [j for j in range(len(names)) if j not in shape]
            names, values = [names[j] for j in kept], values[:, kept]
        col = {c: i for i, c in enumerate(names)}
        drawn = np.flatnonzero(whole)
        joined = np.concatenate([[False], np.diff(drawn) == 1])  # no trail across a gap
        t, values = t[whole], values[whole]
        tips = values[:, [col[c] for c in TIP_COLUMNS]]
        geom = None
        if self.tendon is not None or all(
            o.name in col for o in self.outputs if o.name in self._shape_angles
        ):
            geom, _ = self._row_shapes(t, values, names)
        forces = (
            values[:, [col[c] for c in TIP_FORCE_COLUMNS]]
            if all(c in col for c in TIP_FORCE_COLUMNS)
            else None
        )
        self._send_shapes("truth", t, geom, tips, joined, forces)
        ends = [
            named
            for named in map(self._section_end_names, sections)
            if named and all(c in col for c in named)
        ]
        if ends:
            pts = np.stack([values[:, [col[c] for c in named]] for named in ends], axis=1)
            self.rec.send_columns(
                "world/truth/section_ends",
                indexes=[self.rr.TimeColumn("t", duration=nanoseconds(t))],
                columns=self.rr.Points3D.columns(
                    positions=pts.reshape(-1, 3),
                    radii=[0.012 * self.robot.length] * pts.shape[0] * pts.shape[1],
                    colors=[TRUTH_COLOUR] * pts.shape[0] * pts.shape[1],
                ).partition([len(ends)] * len(t)),
            )
        return geom is not None

    def _finish_file(self, tmp: Path) -> None:
        """Write out the .rrd and rename it into place, or a one-line
        :class:`InputError` naming the file and why (a full disk) where Rerun could
        not (the caller removes the temporary file)."""
        path = self.sink.path
        assert path is not None  # checked by ViewerSink
        try:
            self._flush_file()
            self.rec.disconnect()
            os.replace(tmp, path)
        except (RuntimeError, OSError) as exc:
            folder = path.parent  # "." for a bare file name
            reason = str(getattr(exc, "strerror", None) or exc)
            if self._stuck:
                reason = f"Rerun's file writer did not finish in {FLUSH_TIMEOUT_S:g} s"
            if free_bytes(folder) < DISK_NEARLY_FULL:  # Rerun's writer thread names no
                reason = os.strerror(errno.ENOSPC)  # cause
            raise InputError(f"{path}: cannot write ({reason}) (nothing written)") from None

    def _flush_file(self) -> None:
        """Wait for Rerun to write out what it holds (a RuntimeError where it cannot).
        A writer that has not finished within :data:`FLUSH_TIMEOUT_S`, or whose file
        stopped growing for a :data:`FLUSH_SLICE_S` on a full disk, is taken as stuck
        (:func:`_leave_unclosed`)."""
        started = time.monotonic()
        assert self.sink.path is not None  # a .rrd is being written (ViewerSink)
        folder = self.sink.path.parent
        size = self._written_bytes()
        while True:
            left = FLUSH_TIMEOUT_S - (time.monotonic() - started)
            wait = min(FLUSH_SLICE_S, max(left, 0.05))  # 0 would not wait at all
            sliced = time.monotonic()
            try:
                self.rec.flush(timeout_sec=wait)
                return
            except RuntimeError as exc:
                waited = time.monotonic() - sliced >= 0.9 * wait
                if not (waited or "timed out" in str(exc).lower()):
                    raise  # a write that failed
                before, size = size, self._written_bytes()
                full = size == before and free_bytes(folder) < DISK_NEARLY_FULL
                if full or time.monotonic() - started >= 0.9 * FLUSH_TIMEOUT_S:
                    self._stuck = True
                    _leave_unclosed(self.rr, self.rec)
                    raise

    def _written_bytes(self) -> int:
        """The size of the .rrd's temporary file so far (-1 where there is none)."""
        try:
            return self._tmp.stat().st_size if self._tmp is not None else -1
        except OSError:
            return -1

    def close(
        self, wait: bool = False, keep: bool = True, say: Callable[[str], None] | None = None
    ) -> None:
        """Finish the stream: rename the .rrd into place (without ``keep``: remove it,
        a view that failed writes nothing), or (``wait``) keep the web viewer up until
        Ctrl-C, then stop it; ``say`` takes the lines that say where it serves and that
        it stopped (without it they are :class:`ViewNote` warnings: a call that blocks
        until Ctrl-C says where to look)."""
        if self._closed:
            return

        def said(line: str) -> None:
            if say is not None:
                say(line)
            else:
                warnings.warn(line, ViewNote, stacklevel=3)

        if self._undrawn is not None and self._undrawn.output is not None:
            # the last estimate, which max_hz left undrawn: the view ends where live did
            self.rec.set_time("t", duration=nanoseconds(self._undrawn.t))
            self._draw_estimate(self._undrawn, self._undrawn.output)
        try:
            if self.sink.kind == "save" and self._tmp is not None and keep:
                self._finish_file(self._tmp)
                self._tmp = None
            elif self.sink.kind == "save":
                with contextlib.suppress(RuntimeError):  # a file not kept: whatever Rerun
                    self._flush_file()  # could not write goes with it
            else:  # a viewer that went away, or never came up, holds a flush for ever
                try:
                    self.rec.flush(timeout_sec=FLUSH_TIMEOUT_S)
                except RuntimeError as exc:
                    self._stuck = True
                    _leave_unclosed(self.rr, self.rec)  # its end would wait for the viewer
                    raise InputError(
                        f"the Rerun viewer did not take the view within {FLUSH_TIMEOUT_S:g} s "
                        f"({exc}): the estimates are not drawn there"
                    ) from None
            if self.sink.kind == "web" and wait and self._web is not None:
                said(f"serving the view at {self.sink.web_url} (Ctrl-C stops)")
                try:
                    while self._web.poll() is None:
                        time.sleep(0.2)
                except KeyboardInterrupt:
                    said("stopped serving the view")
        finally:
            if not self._stuck and (self._tmp is not None or self.sink.kind != "save"):
                self.rec.disconnect()  # before the server stops: no broken-connection noise
            if self._tmp is not None:
                self._tmp.unlink(missing_ok=True)
            self._closed = True
            stop_web_viewer(self._web)
