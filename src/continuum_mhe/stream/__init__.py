"""The serial IMU stream of ``continuum-mhe live`` and ``calibrate``: the line protocol
(:mod:`.protocol`), the device's clock (:mod:`.clock`), the port reader
(:mod:`.reader`), recordings and estimate files written row by row
(:mod:`.recording`), and the calibration statistics (:mod:`.calibrate`)."""
