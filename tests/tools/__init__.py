"""Tests of the tools and figures (benchmarks, teleoperation, figure commands)."""
