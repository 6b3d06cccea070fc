"""Offline data: Minari datasets of episodes (:mod:`agents.offline.collection`)."""
