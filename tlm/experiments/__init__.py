"""Experiments: one run, and (later) sweeps, calibration and error-versus-cost studies."""
