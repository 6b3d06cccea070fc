"""Environment wrappers a run config names in ``env_wrapper``: the time feature
(:mod:`.time_feature`), the action history (:mod:`.action_history`), the residual on the loop
plan (:mod:`.residual`) and the Box/Dict observation helpers they share (:mod:`.obs_features`)."""
