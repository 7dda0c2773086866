"""Rotation math and forward kinematics: torch kernels with thin NumPy wrappers."""
