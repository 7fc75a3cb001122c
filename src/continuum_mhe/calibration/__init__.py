"""IMU calibration from recordings or the serial stream: each IMU's statistics and
mounting with the robot straight and still (:mod:`.at_rest`), each IMU's yaw about
the tangent from a bend in a known plane (:mod:`.bend`), and the robot calibrated from
them, as ``continuum-mhe calibrate`` does (:mod:`.robot_calibration`,
``continuum_mhe.calibrate_robot``)."""
