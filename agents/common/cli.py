"""Errors and entry point of the command-line tools: a wrong input is one line and exit code 2.

:class:`UserError` is a wrong input (unknown env id, missing config key, bad keyword,
unreadable model); :func:`run_cli` prints it as ONE line on stderr and exits with code 2.
:func:`parse_kv` reads ``key:value`` command-line items.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from typing import Any

import yaml


class UserError(Exception):
    """A wrong input; the CLIs print its message as one line and exit with code 2."""


def run_cli(main: Callable[[Sequence[str] | None], Any], argv: Sequence[str] | None = None) -> None:
    """Run a CLI ``main``; a :class:`UserError` becomes ``error: <msg>`` on stderr, exit 2."""
    try:
        main(argv)
    except UserError as exc:
        msg = " ".join(str(exc).split())  # one line
        print(f"error: {msg}", file=sys.stderr)
        sys.exit(2)


def parse_kv(items: Sequence[str] | None, what: str = "--env-kwargs") -> dict[str, Any]:
    """``["k:v", ...]`` -> dict, each value parsed as YAML (``0.5``, ``true``, ``[6, 6]``)."""
    out: dict[str, Any] = {}
    for item in items or ():
        key, sep, value = item.partition(":")
        if not sep or not key:
            raise UserError(f"{what} expects key:value items (got {item!r})")
        try:
            out[key] = yaml.safe_load(value)
        except yaml.YAMLError:
            raise UserError(f"{what}: cannot parse the value of {item!r}") from None
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
