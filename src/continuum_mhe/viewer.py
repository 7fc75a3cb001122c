"""A 3D view of the estimated backbone in Rerun: ``continuum-mhe view`` (replay of an
estimate CSV) and the per-estimate hook of ``live --view``.

Every shape comes from the robot and the PCC model (:func:`~continuum_mhe.model.pcc.pose_at`
at ``points_per_section`` arc lengths per section); nothing here knows a size.
Entities, on the timeline ``t`` (the sample time in s, as in the estimate CSV):

- ``world``: view coordinates from the robot's mounting (base z up, or z down); ``world/base``
  the base frame's axes (static).
- ``world/estimate/backbone``: one line strip per section, base to tip (m).
- ``world/estimate/imu_<i>``: IMU ``i``'s sensor frame (robot-file order, its ``mount_rpy``
  applied) as ``Transform3D`` and ``TransformAxes3D``.
- ``world/estimate/tip``: the tip; ``world/estimate/tip_trail``: one segment per estimate,
  from the previous tip, shown for the last ``trail_s`` seconds (a blueprint override), so
  the file grows by a constant amount per sample.
- ``world/truth/{tip,tip_trail}``: a truth CSV's ``x, y, z``; ``world/truth/section_ends``
  its section ends; ``world/truth/backbone`` the PCC curve through its bends, where given.
- ``outputs/<unit>``: the outputs of that unit (``m``, ``rad``) as one batch of scalars
  per sample, named by a static ``SeriesLines`` (``x``, ``theta_1``...).
- ``status``: a text line whenever the status changes (``dropout``, ``reset``...).

A sample without an estimate clears ``world/estimate`` (no stale shape is ever shown) and
breaks the trail. ``rerun-sdk`` is an optional dependency (``pip install
'continuum-mhe[view]'``); this module imports it only when a view is opened.
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import socket
import subprocess
import sys
import time
import uuid
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any, Literal
from urllib.parse import quote

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from continuum_mhe.io.csv_files import FloatArray, InputError, read_state_table
from continuum_mhe.io.raw_imu import mount_rotation
from continuum_mhe.model.descriptions import OutputSpec, pcc_outputs, section_bends
from continuum_mhe.model.pcc import pose_at_sym
from continuum_mhe.model.robot import Robot
from continuum_mhe.results import Estimate

INSTALL_HINT = "pip install 'continuum-mhe[view]'"
APPLICATION_ID = "continuum-mhe"
LOOPBACK = "127.0.0.1"
#: colours of successive sections (RGB), repeated beyond four sections
SECTION_COLOURS = ((31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40))
TRUTH_COLOUR = (150, 150, 150)
TRAIL_COLOUR = (227, 119, 194)


def require_rerun() -> Any:
    """The ``rerun`` module, or one line naming the install command (InputError, exit 2)."""
    try:
        import rerun
    except ImportError:
        raise InputError(f"the 3D view needs rerun-sdk: {INSTALL_HINT}") from None
    return rerun


# --- geometry (pure, numpy) --------------------------------------------------------------
@dataclass(frozen=True)
class BackboneGeometry:
    """Shapes for drawing, for ``n`` samples of one robot.

    Attributes:
        sections: (n, n_sections, points_per_section + 1, 3) m, each section's backbone
            from its base to its end (a section starts where the one below it ends).
        imu_rotation: (n, n_imus, 3, 3) sensor-to-base rotation of each IMU.
        imu_position: (n, n_imus, 3) m.
    """

    sections: FloatArray
    imu_rotation: FloatArray
    imu_position: FloatArray

    @property
    def tip(self) -> FloatArray:
        """(n, 3) m."""
        return self.sections[:, -1, -1]


@cache
def _geometry_function(
    lengths: tuple[float, ...], places: tuple[tuple[int, float], ...], points: int
) -> ca.Function:
    """One CasADi function: bends (2 n_sections,) -> backbone points (3, n_sections *
    points) and IMU poses (9 n_imus column-major rotations, 3 n_imus positions)."""
    u = ca.SX.sym("u", 2 * len(lengths))
    bends = [(u[2 * k], u[2 * k + 1]) for k in range(len(lengths))]
    pts = [
        pose_at_sym(bends, lengths, k, j / points)[1]
        for k in range(len(lengths))
        for j in range(1, points + 1)
    ]
    poses = [pose_at_sym(bends, lengths, sec, at) for sec, at in places]
    rot = ca.vertcat(*[ca.reshape(r, 9, 1) for r, _ in poses])
    pos = ca.vertcat(*[p for _, p in poses])
    return ca.Function("backbone_geometry", [u], [ca.horzcat(*pts), rot, pos])


def backbone_geometry(
    robot: Robot, bends: FloatArray, points_per_section: int = 16
) -> BackboneGeometry:
    """Backbone and IMU frames from bend vectors ``bends`` (n, n_sections, 2) rad."""
    u = np.asarray(bends, dtype=float)
    if u.ndim != 3 or u.shape[1:] != (robot.n_sections, 2):
        raise ValueError(f"bends must be (n, {robot.n_sections}, 2), got {u.shape}")
    n, n_sec, m = u.shape[0], robot.n_sections, points_per_section
    places = tuple((imu.section, float(imu.at)) for imu in robot.imus)
    fn = _geometry_function(robot.lengths, places, m)
    pts, rot, pos = (np.asarray(v, dtype=float) for v in fn.map(n)(u.reshape(n, -1).T))
    pts = pts.reshape(3, n, n_sec, m).transpose(1, 2, 3, 0)  # (n, n_sec, m, 3)
    starts = np.concatenate([np.zeros((n, 1, 3)), pts[:, :-1, -1]], axis=1)
    sections = np.concatenate([starts[:, :, None, :], pts], axis=2)
    n_imus = robot.n_imus
    rot = rot.reshape(n_imus, 3, 3, n).transpose(3, 0, 2, 1)  # column-major blocks
    mounts = np.stack([mount_rotation(imu.mount_rpy) for imu in robot.imus])
    rot = np.einsum("nkij,kjl->nkil", rot, mounts)
    pos = pos.reshape(n_imus, 3, n).transpose(2, 0, 1)
    return BackboneGeometry(sections, rot, pos)


# --- where the view goes ----------------------------------------------------------------
SinkKind = Literal["save", "spawn", "web"]


@dataclass(frozen=True)
class ViewerSink:
    """Where the stream goes.

    Attributes:
        kind: ``save`` (an .rrd file at ``path``), ``spawn`` (Rerun's native viewer), or
            ``web`` (Rerun's web viewer served on 127.0.0.1 only).
        path: the .rrd file for ``save``.
        web_port: HTTP port of the web viewer (``web``).
        grpc_port: port of the Rerun server the stream goes to (``web``, ``spawn``).
    """

    kind: SinkKind
    path: Path | None = None
    web_port: int = 9090
    grpc_port: int = 9876

    def __post_init__(self) -> None:
        if self.kind == "save" and (self.path is None or self.path.suffix.lower() != ".rrd"):
            raise InputError(f"{self.path}: the view is saved as a Rerun file ending in .rrd")
        for name in ("web_port", "grpc_port"):
            v = getattr(self, name)
            if not (isinstance(v, int) and 0 < v < 65536):
                raise InputError(f"--{name.replace('_', '-')} must be a port in 1..65535, got {v}")

    @property
    def web_url(self) -> str:
        proxy = f"rerun+http://{LOOPBACK}:{self.grpc_port}/proxy"
        return f"http://{LOOPBACK}:{self.web_port}/?url={quote(proxy, safe='')}"


def _check_free(port: int, option: str) -> None:
    with socket.socket() as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as servers do: a listener
        try:  # blocks, a closed connection's TIME_WAIT does not
            s.bind((LOOPBACK, port))
        except OSError:
            raise InputError(
                f"port {port} on {LOOPBACK} is in use; pick another with {option}"
            ) from None


def _wait_for_port(port: int, proc: subprocess.Popen[bytes], seconds: float = 20.0) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise InputError(
                f"the Rerun web viewer exited at start (status {proc.returncode}); "
                f"is port {port} already in use?"
            )
        with socket.socket() as s:
            s.settimeout(0.2)
            if s.connect_ex((LOOPBACK, port)) == 0:
                return
        time.sleep(0.1)
    raise InputError(f"the Rerun web viewer did not open port {port} within {seconds:g} s")


def _stop(proc: subprocess.Popen[bytes] | None) -> None:
    """Stop the web viewer process group this module started."""
    if proc is None or proc.poll() is not None:
        return
    try:
        if hasattr(os, "killpg"):
            os.killpg(proc.pid, signal.SIGTERM)
        else:
            proc.terminate()
        proc.wait(timeout=5)
    except (ProcessLookupError, subprocess.TimeoutExpired):
        proc.kill()


# --- the view -----------------------------------------------------------------------------
class BackboneView:
    """A Rerun recording of backbone estimates (see the module doc for its entities).

    ``log_estimate`` is the per-estimate hook of ``live``; ``log_rows`` replays arrays.
    Call ``close`` at the end (it finishes the .rrd file, or stops the web viewer).
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
        self._web: subprocess.Popen[bytes] | None = None
        self._tmp: Path | None = None
        self._prev_tip: dict[str, FloatArray | None] = {"estimate": None, "truth": None}
        self._status = ""
        self._min_step = 1.0 / max_hz if max_hz else 0.0
        self._drawn_t: float | None = None
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
            # written beside the target and renamed at close: never a half-written .rrd
            self._tmp = folder / f".{sink.path.name}.{os.getpid()}.tmp"
            self.rec.save(self._tmp, default_blueprint=blueprint)
        elif sink.kind == "spawn":
            if sys.platform.startswith("linux") and not (
                os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
            ):
                raise InputError(
                    "--spawn needs a display (DISPLAY is not set); "
                    "use --serve-web or --save FILE.rrd"
                )
            self.rec.spawn(port=sink.grpc_port, default_blueprint=blueprint)
        else:
            _check_free(sink.web_port, "--web-port")
            _check_free(sink.grpc_port, "--grpc-port")
            cmd = [
                sys.executable, "-m", "rerun", "--serve-web", "--bind", LOOPBACK,
                "--web-viewer-port", str(sink.web_port), "--port", str(sink.grpc_port),
            ]  # fmt: skip
            self._web = subprocess.Popen(
                cmd,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                start_new_session=True,
            )
            _wait_for_port(sink.web_port, self._web)
            _wait_for_port(sink.grpc_port, self._web)
            self.rec.connect_grpc(
                f"rerun+http://{LOOPBACK}:{sink.grpc_port}/proxy", default_blueprint=blueprint
            )

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
            level = "INFO" if status == "ok" else "WARN"
            self.rec.log("status", self.rr.TextLog(f"status: {status}", level=level))
            self._status = status

    def log_estimate(self, est: Estimate) -> None:
        """The live hook: log one estimate (its ``output`` in ``outputs`` order), one
        entity at a time (``log_rows`` sends a whole recording as columns)."""
        rr, rec, size = self.rr, self.rec, self.robot.length
        rec.set_time("t", duration=float(est.t))
        changed = str(est.status) != self._status
        self._log_status(str(est.status))
        out = est.output
        if out is None or est.status == "no-estimate" or not np.all(np.isfinite(out)):
            rec.log("world/estimate", rr.Clear(recursive=True))
            self._prev_tip["estimate"] = None
            self._drawn_t = None
            return
        if (
            not changed
            and self._drawn_t is not None
            and 0 <= est.t - self._drawn_t < self._min_step
        ):
            return  # max_hz: drawn often enough (status changes and gaps always are)
        self._drawn_t = float(est.t)
        geom = backbone_geometry(self.robot, self._bends(out[None, :]), self.points_per_section)
        colours, labels = self._style("estimate")
        rec.log(
            "world/estimate/backbone",
            rr.LineStrips3D(list(geom.sections[0]), radii=0.01 * size, colors=colours,
                            labels=labels),
        )  # fmt: skip
        tip = geom.tip[0]
        rec.log("world/estimate/tip", rr.Points3D([tip], radii=0.015 * size))
        prev = self._prev_tip["estimate"]
        if prev is not None:
            rec.log(
                "world/estimate/tip_trail",
                rr.LineStrips3D([[prev, tip]], radii=0.004 * size, colors=[TRAIL_COLOUR]),
            )
        self._prev_tip["estimate"] = tip
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
                     tips: FloatArray, joined: NDArray[np.bool_]) -> None:  # fmt: skip
        """Columns of one recording's shapes at times ``t`` (n,): the backbone and IMU
        frames of ``geom`` (if any), the ``tips`` (n, 3) m and their trail; ``joined[k]``
        is True where sample ``k`` continues the trail from sample ``k - 1``."""
        rr, rec, size = self.rr, self.rec, self.robot.length
        n, n_sec = len(t), self.robot.n_sections
        colours, labels = self._style(who)

        def send(entity: str, times: FloatArray, columns: Any) -> None:
            rec.send_columns(entity, indexes=[rr.TimeColumn("t", duration=times)],
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
        if who == "truth" or geom is None:
            return
        for i in range(self.robot.n_imus):
            send(
                f"world/{who}/imu_{i + 1}", t,
                [*rr.Transform3D.columns(translation=geom.imu_position[:, i],
                                         mat3x3=geom.imu_rotation[:, i]),
                 *rr.TransformAxes3D.columns(axis_length=[0.1 * size] * n)],
            )  # fmt: skip

    def log_rows(self, t: FloatArray, values: FloatArray, status: Sequence[str]) -> None:
        """Send a recording's estimates as columns: ``t`` (n,) s, ``values`` (n,
        n_outputs) in ``outputs`` order (m, rad; NaN where there is no estimate),
        ``status`` (n,). Draws what ``log_estimate`` draws row by row."""
        t = np.asarray(t, dtype=float)
        values = np.asarray(values, dtype=float).reshape(len(t), len(self.outputs))
        has = np.all(np.isfinite(values), axis=1) & (np.asarray(status) != "no-estimate")
        for k in range(len(t)):  # status changes and clears: few rows, one at a time
            if str(status[k]) != self._status or not has[k]:
                self.rec.set_time("t", duration=float(t[k]))
                self._log_status(str(status[k]))
                if not has[k]:
                    self.rec.log("world/estimate", self.rr.Clear(recursive=True))
        if not has.any():
            return
        geom = backbone_geometry(self.robot, self._bends(values[has]), self.points_per_section)
        joined = (has & np.concatenate([[False], has[:-1]]))[has]
        self._send_shapes("estimate", t[has], geom, geom.tip, joined)
        n = int(has.sum())
        for unit, cols in self._units.items():
            self.rec.send_columns(
                f"outputs/{unit}",
                indexes=[self.rr.TimeColumn("t", duration=t[has])],
                columns=self.rr.Scalars.columns(scalars=values[has][:, cols].ravel()).partition(
                    [len(cols)] * n
                ),
            )
        self._prev_tip["estimate"] = geom.tip[-1] if has[-1] else None

    def log_truth(self, t: FloatArray, values: FloatArray, names: Sequence[str]) -> bool:
        """Send a truth recording: ``values`` (n, len(names)), columns named as in a truth
        CSV. The tip and its trail are its ``x, y, z``; each section end ``x_k, y_k,
        z_k`` it has is a point (``world/truth/section_ends``); the backbone is drawn by
        the PCC model from its ``theta, phi`` columns, where it has them all (on rod
        data the PCC curve through the true bends, not the rod itself). Returns whether
        the backbone was drawn."""
        t = np.asarray(t, dtype=float)
        values = np.asarray(values, dtype=float)
        col = {c: i for i, c in enumerate(names)}
        tips = values[:, [col[c] for c in "xyz"]]
        geom = None
        if all(o.name in col for o in self.outputs if o.unit == "rad"):
            ordered = values[:, [col.get(o.name, col["x"]) for o in self.outputs]]
            geom = backbone_geometry(self.robot, self._bends(ordered), self.points_per_section)
        self._send_shapes("truth", t, geom, tips, np.arange(len(t)) > 0)
        ends = [k for k in range(1, self.robot.n_sections + 1) if f"x_{k}" in col]
        if ends:
            pts = np.stack([values[:, [col[f"{c}_{k}"] for c in "xyz"]] for k in ends], axis=1)
            self.rec.send_columns(
                "world/truth/section_ends",
                indexes=[self.rr.TimeColumn("t", duration=t)],
                columns=self.rr.Points3D.columns(
                    positions=pts.reshape(-1, 3),
                    radii=[0.012 * self.robot.length] * pts.shape[0] * pts.shape[1],
                    colors=[TRUTH_COLOUR] * pts.shape[0] * pts.shape[1],
                ).partition([len(ends)] * len(t)),
            )
        return geom is not None

    def close(self, wait: bool = False) -> None:
        """Finish the stream: rename the .rrd into place, or (``wait``) keep the web
        viewer up until Ctrl-C, then stop it."""
        try:
            self.rec.flush()
            if self.sink.kind == "save" and self._tmp is not None:
                self.rec.disconnect()
                assert self.sink.path is not None
                os.replace(self._tmp, self.sink.path)
                self._tmp = None
            elif self.sink.kind == "web" and wait and self._web is not None:
                print(f"serving the view at {self.sink.web_url} (Ctrl-C stops)", file=sys.stderr)
                try:
                    while self._web.poll() is None:
                        time.sleep(0.2)
                except KeyboardInterrupt:
                    print("stopped serving the view", file=sys.stderr)
        finally:
            if self._tmp is not None:
                self.rec.disconnect()
                self._tmp.unlink(missing_ok=True)
            _stop(self._web)


# --- replay -------------------------------------------------------------------------------
def _columns(
    path: str, names: Sequence[str], outputs: Sequence[OutputSpec], robot: Robot
) -> list[int]:
    """Indices of ``outputs`` in a CSV's columns; one line when they do not fit the robot."""
    missing = [o.name for o in outputs if o.name not in names]
    extra_sections = [
        n for n in names if n.startswith("theta_") and n not in {o.name for o in outputs}
    ]
    if missing or extra_sections:
        has = [n for n in names if n.startswith("theta")]
        raise InputError(
            f"{path}: its columns ({', '.join(has) or 'no theta'}) do not fit the robot "
            f"({robot.describe()}): missing {', '.join(missing) or 'none'}"
            f"{'; extra ' + ', '.join(extra_sections) if extra_sections else ''}; pass --robot"
        )
    return [list(names).index(o.name) for o in outputs]


def replay(
    estimates: str, robot: Robot, sink: ViewerSink, truth: str | None = None,
    trail_s: float = 10.0, points_per_section: int = 16,
) -> int:  # fmt: skip
    """Write or show the view of an estimate CSV (and its truth). Returns the number of
    estimates drawn."""
    outputs = pcc_outputs(robot.n_sections)
    est = read_state_table(estimates, ())
    cols = _columns(estimates, est.names, outputs, robot)
    truth_table = None
    if truth is not None:
        truth_table = read_state_table(truth)  # t, x, y, z and any per-section columns
        extra = [n for n in truth_table.names if n.startswith("theta_")]
        if len(extra) > (robot.n_sections if robot.n_sections > 1 else 0):
            raise InputError(f"{truth}: its columns ({', '.join(extra)}) do not fit the "
                             f"robot ({robot.describe()}); pass --robot")  # fmt: skip
    view = BackboneView(
        robot, outputs, sink, trail_s=trail_s, points_per_section=points_per_section,
        name=Path(estimates).name,
    )  # fmt: skip
    with_truth = ""
    try:
        if truth_table is not None:
            drawn_truth = view.log_truth(truth_table.t, truth_table.values, truth_table.names)
            with_truth = ", with truth" + (
                ""
                if drawn_truth
                else " (tip and section ends only: no theta/phi columns for every section)"
            )
        view.log_rows(est.t, est.values[:, cols], list(est.status))
    except BaseException:
        view.close()
        raise
    drawn = int(np.sum(np.all(np.isfinite(est.values[:, cols]), axis=1)))
    where = {
        "save": f"wrote {sink.path}",
        "spawn": "sent to the Rerun viewer",
        "web": "sent to the web viewer",
    }[sink.kind]
    print(
        f"{where}: {drawn} of {len(est.t)} estimate(s) of {robot.describe()}{with_truth}",
        file=sys.stderr,
    )
    view.close(wait=True)
    return drawn


def cmd_view(args: argparse.Namespace) -> int:
    from continuum_mhe.cli_options import robot_from_args, viewer_sink_from_args

    sink = viewer_sink_from_args(args)
    replay(args.estimates, robot_from_args(args), sink, args.truth, args.trail, args.points)
    return 0


def register(subparsers: Any) -> None:
    """Add ``view``."""
    from continuum_mhe.cli_options import add_robot_option, add_viewer_options
    from continuum_mhe.model.imu import MOUNTINGS

    p = subparsers.add_parser(
        "view",
        help="3D view of an estimate CSV in Rerun (backbone, IMU frames, tip trail)",
        description="Replay an estimate CSV as a 3D view in Rerun: every section of the "
        f"backbone, the IMU frames and the tip trail. Needs rerun-sdk ({INSTALL_HINT}).",
    )
    p.add_argument("estimates", metavar="EST.csv", help="estimate CSV (from estimate or live)")
    p.add_argument("--truth", metavar="TRUTH.csv", help="truth CSV, drawn in grey")
    add_robot_option(p)
    p.add_argument("--length", type=float, default=0.2, help="section length in m (default 0.2)")
    p.add_argument("--mounting", choices=MOUNTINGS, default="z-up", help="base orientation")
    add_viewer_options(p)
    p.set_defaults(func=cmd_view)
