"""Agents for the soft-hand environments: scripted policies, SB3 training and evaluation.

Commands (``python -m agents.<name>``, the top level holds only these and three aliases):

* ``train`` (an SB3 run from a hyper-parameter entry), ``distill`` (DAgger: a blind student
  from a privileged teacher), ``evaluate`` (a model or scripted policy on seeded goals),
  ``demo`` (the paper's figures and the headline table), ``pose_figures`` (reachable set and
  manoeuvre of Pose policies), ``learning_curves`` (validation curves of runs),
  ``bench_train`` (PPO speed: dummy vs native vector env, and RLlib), ``rllib_train`` (PPO
  with Ray RLlib, exported as an SB3 run), ``collect`` (Minari datasets of a policy's
  episodes with the privileged state per step), ``bc`` (behaviour cloning on a dataset).

Sub-packages (libraries; no command imports another command's internals):

* ``common``: CLI errors and entry point, the benchmark's success rule, env construction and
  the ``env_wrapper`` allow-list;
* ``runs``: the on-disk run format (layout and file names, reading, writing, typed run
  config and record, SB3 zips without unpickling, observation statistics, RL Zoo's YAML
  dialect, hyper-parameter files, the task keywords the registered id defines);
* ``sb3``: the native vector env as an SB3 ``VecEnv``, asymmetric / blind policies, the goal
  curriculum and the training library of ``train`` and ``distill``;
* ``wrappers``: time feature, action history, the residual on the loop plan;
* ``scripted``: the paper's motions, the handling process, the model-based baseline, the
  loop plan;
* ``play``: the policy of a ``--model`` / ``--policy`` choice, the episode loops of
  ``evaluate`` and ``pose_figures`` and a run's count of scores on the test goals;
* ``plots``: figures of evaluated episodes and of Pose policies;
* ``offline``: dataset ids, episode recording (serial or over Ray workers) and Minari writing,
  the library of ``collect`` and ``bc``;
* ``rllib``: a hyper-parameter entry as RLlib PPO settings, the training loop and the export
  of the RLModule into an SB3 run, the library of ``rllib_train``.

Data: ``configs/`` (hyper-parameter files, RL Zoo's dialect, keyed by env id) and ``models/``
(the shipped models as RL Zoo runs), installed with the package.

``agents.time_feature``, ``agents.action_history`` and ``agents.residual`` are the published
dotted paths of the wrappers that run configs name (``env_wrapper``); they import the classes
from ``wrappers`` (and ``scripted.loop_plan``).
"""
