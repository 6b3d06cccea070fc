"""The on-disk run format (RL Zoo's layout): names of a run's files (:mod:`.layout`), reading
(:mod:`.loading`) and writing (:mod:`.writing`) a run, the typed run config and record
(:mod:`.records`), SB3 zips without unpickling (:mod:`.model_files`), observation statistics
(:mod:`.normalization`), the zoo's YAML dialect (:mod:`.zoo_dialect`) and the hyper-parameter
files (:mod:`.hyperparams`)."""
