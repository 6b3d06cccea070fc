"""Tests of the physics and quasi-static layers (contact, model, kernels, planner)."""
