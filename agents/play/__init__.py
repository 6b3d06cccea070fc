"""Playing a policy: the policy and env of a ``--model`` / ``--policy`` choice
(:mod:`.choice`) and the episode and goal-set loops (:mod:`.rollout`), shared by
``agents.evaluate`` and ``agents.pose_figures``; the count of a run's scores on the test goals
(:mod:`.test_scores`)."""
