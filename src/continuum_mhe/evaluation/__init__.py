"""What is made of recorded estimates: the errors against a truth and the calibration of
the standard deviations (:mod:`.metrics`), and the figures (:mod:`.plotting`). Both read
result data and never an estimator."""
