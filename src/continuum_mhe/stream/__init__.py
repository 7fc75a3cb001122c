"""The serial IMU stream read by ``continuum-mhe live`` and ``calibrate``: the line
protocol (:mod:`.protocol`), the device's clock (:mod:`.clock`), the port reader
(:mod:`.reader`), and recordings and estimate files written row by row
(:mod:`.recording`)."""
