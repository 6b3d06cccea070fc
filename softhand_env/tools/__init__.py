"""Command-line tools: ``python -m softhand_env.tools.<name>``.

:mod:`.bench` (kernel speed), :mod:`.bench_env` (env steps/s), :mod:`.bench_quasistatic`
(quasi-static solver speed), :mod:`.soak` (long random-action run: steps/s, terminations, RSS)
and :mod:`.simulate` (set-point sequences of the dynamic model, the paper's motions 1-8).
"""
