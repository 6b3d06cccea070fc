"""Stable-Baselines3 pieces: the batched env as an SB3 ``VecEnv`` (:mod:`.native_vec_env`),
the asymmetric / blind-actor policies (:mod:`.policies`), the goal curriculum
(:mod:`.curriculum`), the training library that ``agents.train`` and ``agents.distill``
share (:mod:`.training`) and what every distilled student shares (:mod:`.imitation`)."""
