"""Tests of the environments (Gymnasium API, tasks, observations, vector env)."""
