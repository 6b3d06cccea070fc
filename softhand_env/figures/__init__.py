"""Figure commands that reproduce the dissertation's plots.

Usage::

    python -m softhand_env.figures contact --out DIR
    python -m softhand_env.figures dynamics --out DIR
    python -m softhand_env.figures quasistatic --out DIR

Each subcommand lives in its own module ``softhand_env.figures.<name>`` that defines
``add_arguments(parser)``, ``run(args) -> list[pathlib.Path]`` (the files written) and
``OUTPUTS`` (their names: an earlier run's are not overwritten without ``--force``).
Modules are imported lazily so that ``--help`` stays fast and matplotlib is only loaded
when a figure is drawn. One helper module is not a subcommand: ``overlay`` draws text (time,
goal, object pose) on rendered frames (the evaluated-episode plots that use it are
``agents.plots.episodes``).
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence

from softhand_env.cli import ArgumentParser, check_output_dir, run_cli

#: subcommand name -> (module, one-line help)
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "contact": ("softhand_env.figures.contact", "Figs 2.6, 2.7, 2.11, 3.3: fingertip models"),
    "dynamics": ("softhand_env.figures.dynamics", "Figs 5.5, 5.6: CSM run of motions 1-8"),
    "quasistatic": ("softhand_env.figures.quasistatic", "Figs 4.8, 4.9: LMEE handling"),
}


def _run(argv: Sequence[str] | None) -> int:
    parser = ArgumentParser(prog="python -m softhand_env.figures", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    for name, (module_name, help_text) in SUBCOMMANDS.items():
        p = sub.add_parser(name, help=help_text)
        p.add_argument("--out", default=f"out/{name}", help="output directory (created)")
        p.add_argument("--force", action="store_true",
                       help="overwrite the figures of an earlier run in --out")
        module = importlib.import_module(module_name)
        module.add_arguments(p)
        p.set_defaults(_run=module.run, _outputs=module.OUTPUTS)
    args = parser.parse_args(argv)
    check_output_dir(args.out, args._outputs, args.force)
    written = args._run(args)
    for path in written:
        print(path)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Parse ``argv`` and run one figure subcommand; returns the process exit code (0). A
    wrong input (an existing figure in ``--out`` without ``--force``, an unwritable ``--out``,
    a bad value) is one line on stderr and exit code 2, checked before any figure is drawn
    (:func:`softhand_env.cli.run_cli`)."""
    return int(run_cli(_run, argv))
