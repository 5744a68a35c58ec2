"""Passes and the pass planner: the functional frames of an image (no timing)."""
