"""A 3D view of the estimated backbone in Rerun: ``continuum-mhe view`` (replay of an
estimate CSV, :mod:`continuum_mhe.cli.view`) and the per-estimate hook of ``live --view``.

Every shape comes from the robot and the PCC model (:func:`~continuum_mhe.model.pcc.pose_at`
at ``points_per_section`` arc lengths per section), or, for a tendon robot, from its
mechanics model (:class:`~continuum_mhe.viewer.geometry.TendonShapes`: live from each
estimate's state, in a replay from each row's tip force and a tensions file, without
which a replay draws the tips alone); nothing here knows a size.
Entities, on the timeline ``t`` (the sample time in s, as in the estimate CSV):

- ``world``: view coordinates from the robot's mounting (base z up, or z down); ``world/base``
  the base frame's axes (static).
- ``world/estimate/backbone``: one line strip per section, base to tip (m).
- ``world/estimate/imu_<i>``: IMU ``i``'s sensor frame (robot-file order, its ``mount_rpy``
  applied, turned by its estimated twist ``imu_twist_i`` where the estimate has one) as
  ``Transform3D`` and ``TransformAxes3D``.
- ``world/estimate/tip``: the tip (a tendon robot's: the estimate's ``x, y, z``);
  ``world/estimate/tip_trail``: one segment per estimate, from the previous tip, shown for
  the last ``trail_s`` seconds (a blueprint override), so the file grows by a constant
  amount per sample.
- ``world/estimate/tip_force``: a tendon robot's tip force as an arrow from the tip
  (:func:`~continuum_mhe.viewer.view.force_arrow_scale` m per N), labelled in N;
  ``world/truth/tip_force`` the truth's, where it has ``fx, fy, fz``.
- ``world/truth/{tip,tip_trail}``: a truth CSV's ``x, y, z``; ``world/truth/section_ends``
  its section ends; ``world/truth/backbone`` the PCC curve through its bends, where given
  (a tendon robot's: the mechanics model's at its tip force and the tensions).
- ``outputs/<unit>``: the outputs of that unit (``m``, ``rad``; a tendon robot's tip
  force ``N`` and tension gains ``1``) as one batch of scalars per sample, named by a
  static ``SeriesLines`` (``x``, ``theta_1``...).
- ``status``: a text line whenever the status changes (``dropout``, ``reset``...).

A sample without an estimate clears ``world/estimate`` (no stale shape is ever shown) and
breaks the trail. ``rerun-sdk`` is an optional dependency (``pip install
'continuum-mhe[view]'``); this module imports it only when a view is opened.
"""

from __future__ import annotations

from continuum_mhe.viewer.geometry import BackboneGeometry, TendonShapes, backbone_geometry
from continuum_mhe.viewer.replay import read_view_tensions, replay
from continuum_mhe.viewer.sink import ViewerSink
from continuum_mhe.viewer.view import (
    INSTALL_HINT,
    BackboneView,
    ViewNote,
    ViewWarning,
    require_rerun,
)

__all__ = [
    "INSTALL_HINT",
    "BackboneGeometry",
    "BackboneView",
    "TendonShapes",
    "ViewNote",
    "ViewWarning",
    "ViewerSink",
    "backbone_geometry",
    "read_view_tensions",
    "replay",
    "require_rerun",
]
