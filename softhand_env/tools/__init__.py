"""Command-line tools: ``python -m softhand_env.tools.<name>``.

:mod:`.bench` (kernel speed), :mod:`.bench_env` (env steps/s), :mod:`.bench_quasistatic`
(quasi-static solver speed), :mod:`.soak` (long random-action run: steps/s, terminations, RSS),
:mod:`.slip_windows` (friction ratio over windows of physical time, from 1 ms replays) and
:mod:`.observability` (how well an MLP reads the object pose from the observation frames);
:mod:`.integrator_convergence` draws the error of both integrators against the step size.
``softhand_env.tools.simulate`` is a deprecated alias of :mod:`softhand_env.physics.motions`.
"""
