"""Estimation in real time from a serial IMU stream: the session that turns each line
into a measurement and an estimate row (:mod:`.session`) and the loop that reads the
port, keeps up with it and draws (:mod:`.run`). The stream itself (protocol, clock,
port reader, row files) is :mod:`continuum_mhe.stream`."""
