"""Errors and entry point of the ``agents`` commands: a wrong input is one line and exit code 2.

The entry point and the output checks are :mod:`softhand_env.cli`'s (:func:`run_cli`: an
expected failure, e.g. a :class:`UserError`, a ``ValueError`` of a constructor, a YAML error,
an ``OSError``, is ONE line on stderr and exit code 2; a bug keeps its traceback).
:class:`UserError` is a wrong input of these commands (unknown env id, missing config key,
bad keyword, unreadable model); :func:`parse_kv` (:mod:`softhand_env.cli`'s) reads
``key:value`` command-line items;
:func:`check_run_location` keeps runs out of the installed package's model folder.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from softhand_env.cli import (  # noqa: F401  (re-exported for the commands)
    CliError,
    check_output_dir,
    check_output_file,
    one_line,
    parse_kv,
    run_cli,
)

#: A wrong input; the CLIs print its message as one line and exit with code 2 (the class of
#: :mod:`softhand_env.cli`, so the output checks there raise it too).
UserError = CliError


#: Largest seed numpy accepts.
SEED_MAX = 2**32 - 1


class ArgumentParser(argparse.ArgumentParser):
    """argparse whose usage errors are :class:`UserError` (one line, exit code 2 in
    :func:`run_cli`) instead of a usage block."""

    def error(self, message: str):  # type: ignore[override,unused-ignore]
        raise UserError(f"{self.prog}: {message}")


def check_range(name: str, value: float, low: float, high: float) -> None:
    """:class:`UserError` naming ``name`` unless ``low <= value <= high``."""
    if not low <= value <= high:
        raise UserError(f"{name} must be in [{low}, {high}] (got {value})")


#: The installed package's model folder (shipped models; never a place for new runs).
PACKAGE_MODELS = Path(__file__).resolve().parent.parent / "models"


def check_run_location(folder: str | Path, what: str = "--log-folder") -> None:
    """:class:`UserError` if ``folder`` is the installed package's model folder or inside it
    (a run there would be loaded as a shipped model), then :func:`check_output_dir`
    (a directory, writable)."""
    path = Path(folder).resolve()
    if path == PACKAGE_MODELS or PACKAGE_MODELS in path.parents:
        raise UserError(f"{what} {folder} is inside the package's model folder "
                        f"{PACKAGE_MODELS}; runs go elsewhere (e.g. logs)")
    check_output_dir(folder, (), force=True, what=what)
