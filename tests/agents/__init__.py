"""Tests of the agents: scripted policies, training, evaluation, run loading."""
