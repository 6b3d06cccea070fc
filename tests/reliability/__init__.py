"""Reliability tests: determinism, invariants, fuzzing, divergence, soak."""
