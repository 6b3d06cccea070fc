"""Errors and entry point of the ``agents`` commands: a wrong input is one line and exit code 2.

The entry point and the output checks are :mod:`softhand_env.cli`'s (:func:`run_cli`: an
expected failure, e.g. a :class:`UserError`, a ``ValueError`` of a constructor, a YAML error,
an ``OSError``, is ONE line on stderr and exit code 2; a bug keeps its traceback).
:class:`UserError` is a wrong input of these commands (unknown env id, missing config key,
bad keyword, unreadable model); :func:`parse_kv` reads ``key:value`` command-line items;
:func:`check_run_location` keeps runs out of the installed package's model folder.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from softhand_env.cli import (  # noqa: F401  (re-exported for the commands)
    CliError,
    check_output_dir,
    check_output_file,
    one_line,
    run_cli,
)
from softhand_env.physics.safe_yaml import load_bounded

#: A wrong input; the CLIs print its message as one line and exit with code 2 (the class of
#: :mod:`softhand_env.cli`, so the output checks there raise it too).
UserError = CliError


def parse_kv(items: Sequence[str] | None, what: str = "--env-kwargs") -> dict[str, Any]:
    """``["k:v", ...]`` -> dict, each value parsed as YAML (``0.5``, ``true``, ``[6, 6]``) with the
    bounds of :func:`softhand_env.physics.safe_yaml.load_bounded` (no aliases, depth, size)."""
    out: dict[str, Any] = {}
    for item in items or ():
        key, sep, value = item.partition(":")
        if not sep or not key:
            raise UserError(f"{what} expects key:value items (got {item[:80]!r})")
        try:
            out[key] = load_bounded(value, source=f"{what} {key[:80]!r}")
        except ValueError as exc:
            raise UserError(str(exc)) from None
    return out


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
