"""Command-line tools: ``python -m softhand_env.tools.<name>``.

:mod:`.bench` (kernel speed), :mod:`.bench_env` (env steps/s), :mod:`.bench_quasistatic`
(quasi-static solver speed) and :mod:`.soak` (long random-action run: steps/s, terminations,
RSS). ``softhand_env.tools.simulate`` is a deprecated alias of
:mod:`softhand_env.physics.motions`.
"""
