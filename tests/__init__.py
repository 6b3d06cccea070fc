"""Tests of softhand-env; sub-packages mirror the source tree."""
