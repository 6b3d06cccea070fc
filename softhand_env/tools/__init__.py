"""Command-line tools: ``python -m softhand_env.tools.<name>``.

:mod:`.bench` (kernel speed), :mod:`.bench_env` (env steps/s), :mod:`.bench_quasistatic`
(quasi-static solver speed), :mod:`.soak` (long random-action run: steps/s, terminations, RSS),
:mod:`.simulate` (set-point sequences of the dynamic model, the paper's motions 1-8),
:mod:`.slip_windows` (friction ratio over windows of physical time, from 1 ms replays) and
:mod:`.observability` (how well an MLP reads the object pose from the observation frames).
"""
