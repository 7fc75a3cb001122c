"""The two-section rod generator's tendon drive and its twist about the tangent (known
answers, no simulation), and the shipped recordings' info."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from continuum_mhe.model.pcc import section_frames_from_bends
from continuum_mhe.simulation.cosserat_sections import (
    SectionRodSettings,
    SectionTrajectory,
    couples,
    pcc_truth,
    tangent_twist,
)

DATA = Path(__file__).parents[1] / "src/continuum_mhe/data/rod2"


def _rot_z(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    out = np.zeros((*a.shape, 3, 3))
    out[..., 0, 0], out[..., 0, 1], out[..., 1, 0], out[..., 1, 1] = c, -s, s, c
    out[..., 2, 2] = 1.0
    return out


def test_twist_about_the_tangent_is_recovered() -> None:
    """Rod frames made of PCC frames turned about the tangent by known angles: the
    bends come back from the tangents, and the twist is each known angle."""
    rng = np.random.default_rng(4)
    n = 50
    bends = rng.uniform(-1.2, 1.2, size=(n, 2, 2))
    twist = rng.uniform(-2.5, 2.5, size=(n, 2))
    R_true = section_frames_from_bends(bends, (0.16, 0.14)) @ _rot_z(twist)
    directors = np.transpose(R_true, (0, 1, 3, 2))  # PyElastica: rows are d1, d2, d3
    z = np.zeros((n, 2, 3))
    traj = SectionTrajectory(
        np.arange(n) * 1e-3, np.zeros((n, 3, 31)), directors, z, z, np.zeros(n), (16, 30)
    )
    got, _ = pcc_truth(traj, (0.16, 0.14))
    assert_allclose(got, bends, atol=1e-9)
    assert_allclose(tangent_twist(traj, got), twist, atol=1e-9)


def test_tendon_couples_are_follower_couples_with_the_section_moments() -> None:
    """Tendon drive: both couples are perpendicular to the tangent in their own frame,
    section 2 carries ``M_2`` and section 1 ``M_1 = c_1 + c_2``; the planar S bends the
    sections in opposite senses; the base drive is unchanged."""
    s = SectionRodSettings(drive="tendon")
    t = 0.5 * s.period  # the hold: full pull
    for scenario in ("planar-s", "spatial"):
        c1, c2 = couples(scenario, t, s)
        assert c1[2] == 0.0 and c2[2] == 0.0
        assert np.linalg.norm(c2) == pytest.approx(s.tendon_gain[1] * s.max_moment)
        assert np.linalg.norm(c1 + c2) == pytest.approx(s.tendon_gain[0] * s.max_moment)
    c1, c2 = couples("planar-s", t, s)
    assert (c1 + c2)[0] > 0 > c2[0]
    base1, base2 = couples("spatial", t, SectionRodSettings())
    m = 1.3 * SectionRodSettings().max_moment
    assert np.linalg.norm(base2) == pytest.approx(m) and math.isclose(base1[2], 0.0)
    with pytest.raises(ValueError, match="drive"):
        SectionRodSettings(drive="cable")


def test_shipped_recordings_report_their_twist_about_the_tangent() -> None:
    """Every shipped recording's info has the twist about the tangent at both section
    ends; the tendon recording bends over 90 deg per section with under 5 deg of it,
    where the base-frame couples twist the tip by over 90 deg."""
    infos = {
        p.name[: -len("_info.json")]: json.loads(p.read_text()) for p in DATA.glob("*_info.json")
    }
    assert {"planar-s", "spatial", "spatial-stiff-torsion", "spatial-tendon"} <= set(infos)
    for info in infos.values():
        assert len(info["tangent_twist_max_deg"]) == 2
    tendon = infos["spatial-tendon"]
    assert tendon["drive"] == "tendon" and min(tendon["theta_max_deg"]) > 90
    assert max(tendon["tangent_twist_max_deg"]) < 5
    assert infos["spatial"]["tangent_twist_max_deg"][1] > 90
    for p in DATA.iterdir():
        assert p.stat().st_size < 200_000, p.name  # shipped data stays small
