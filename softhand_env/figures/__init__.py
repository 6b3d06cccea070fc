"""Figure commands that reproduce the dissertation's plots.

Usage::

    python -m softhand_env.figures contact --out DIR
    python -m softhand_env.figures dynamics --out DIR
    python -m softhand_env.figures quasistatic --out DIR

Each subcommand lives in its own module ``softhand_env.figures.<name>`` that defines
``add_arguments(parser)`` and ``run(args) -> list[pathlib.Path]`` (the files written).
Modules are imported lazily so that ``--help`` stays fast and matplotlib is only loaded
when a figure is drawn. One helper module is not a subcommand: ``overlay`` draws text (time,
goal, object pose) on rendered frames (the evaluated-episode plots that use it are
``agents.plots.episodes``).
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

#: subcommand name -> (module, one-line help)
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "contact": ("softhand_env.figures.contact", "Figs 2.6, 2.7, 2.11, 3.3: fingertip models"),
    "dynamics": ("softhand_env.figures.dynamics", "Figs 5.5, 5.6: CSM run of motions 1-8"),
    "quasistatic": ("softhand_env.figures.quasistatic", "Figs 4.8, 4.9: LMEE handling"),
}


def main(argv: Sequence[str] | None = None) -> int:
    """Parse ``argv`` and run one figure subcommand; returns the process exit code."""
    parser = argparse.ArgumentParser(prog="python -m softhand_env.figures", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    for name, (module_name, help_text) in SUBCOMMANDS.items():
        p = sub.add_parser(name, help=help_text)
        p.add_argument("--out", default=f"out/{name}", help="output directory (created)")
        module = importlib.import_module(module_name)
        module.add_arguments(p)
        p.set_defaults(_run=module.run)
    args = parser.parse_args(argv)
    try:
        written = args._run(args)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for path in written:
        print(path)
    return 0
