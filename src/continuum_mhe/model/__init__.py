"""Pure model functions: kinematics, IMU measurement model, motion formulations."""
