"""continuum-mhe: shape and tip estimation of continuum robots from a tip IMU."""
