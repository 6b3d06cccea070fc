"""RLlib (Ray) PPO training and its export to an SB3 run: the library of ``agents.rllib_train``.

``settings`` (our PPO entry as RLlib settings; pure Python, no Ray import), ``algorithm``
(the RLlib algorithm: ``PPOConfig``, env creator, training loop), ``export`` (the RLModule's
weights and the observation filter as an SB3 PPO run).
"""
