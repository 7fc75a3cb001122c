"""The live summary's line on IMUs that twist about the backbone: ``live`` keeps the
IMUs' constant-curvature frames (a stream gives no recording to weigh the twist on
first, as ``estimate`` does), and weighs the twist alongside on the readings it
estimated (:class:`~continuum_mhe.estimators.twist_evidence.StreamedTwistEvidence`),
to say at the end where the twist would have followed the robot."""

from __future__ import annotations

from continuum_mhe.estimators.twist_evidence import TwistEvidence


def twist_hint(evidence: TwistEvidence | None, calibrated: bool, inconsistent: bool) -> str | None:
    """The summary's warning where the session's readings show the IMUs twisting
    (``evidence.twists``): with every IMU's gyro bias ``calibrated`` always, as
    ``estimate`` of the recording would then estimate the twist; uncalibrated only for
    a session the model did not fit (the warning on ``inconsistent`` estimates), as
    ``estimate``'s own hint. None otherwise."""
    if evidence is None or not evidence.twists or not (calibrated or inconsistent):
        return None
    said = (
        "the readings show the IMUs turning about the backbone, which the "
        "constant-curvature frames that live keeps do not follow (a model of each IMU's "
        f"twist predicted {evidence.said}): "
    )
    if calibrated:
        return said + (
            "live --imu-twist follows it; estimate of the session's recording (live "
            "--record RAW.csv), given --robot and not --config, weighs the twist and "
            "estimates with it (docs/model.md, The IMUs' twist)"
        )
    return said + (
        "calibrate the gyro biases with the robot straight and still (continuum-mhe "
        "calibrate --port PORT --robot ROBOT.toml --write-robot CAL.toml), then live "
        "--robot CAL.toml --imu-twist follows it; uncalibrated, --imu-twist takes a gyro's "
        "bias about its z axis for a twist (docs/model.md, The IMUs' twist)"
    )
