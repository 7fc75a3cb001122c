"""IMU calibration from recordings or the serial stream: each IMU's statistics and
mounting with the robot straight and still (:mod:`.at_rest`), and each IMU's yaw about
the tangent from a bend in a known plane (:mod:`.bend`)."""
