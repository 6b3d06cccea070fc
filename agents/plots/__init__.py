"""Figures of evaluated agents: episode trajectories, titles and GIF frames for
``agents.evaluate`` (:mod:`.episodes`), the reachable-set and manoeuvre plots of
``agents.pose_figures`` (:mod:`.pose`)."""
