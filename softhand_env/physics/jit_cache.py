"""One freshness stamp for numba's on-disk caches of the package's compiled functions.

numba keeps a compiled function (``@njit(cache=True)``) on disk and reuses it while the source
file that defines it is unchanged. A compiled function also contains the code of the compiled
functions it calls from *other* modules: after an edit of ``rosenbrock.py`` alone, the cached
control step of ``envs/fused.py`` would still run the old integrator. This module gives every
cached function of the package one stamp instead of its own file's, the SHA-256 of all the
package's modules that define cached functions (:data:`JIT_MODULES`), so that an edit of any of
them recompiles all of them. Paths, file names and everything else of the cache stay numba's.

Importing this module installs the stamp (:func:`install`); each module in
:data:`JIT_MODULES` imports it before its first decorator, since numba chooses a function's
cache when the decorator runs. Installing does nothing where numba's cache internals differ
from those this was written against (numba 0.68's ``CacheImpl._locator_classes``; earlier
releases name the class ``_CacheImpl``), or when ``NUMBA_CACHE_LOCATOR_CLASSES`` chooses the
cache classes: caching then works as numba's default.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Any

#: Directory of the ``softhand_env`` package.
PACKAGE_DIR = Path(__file__).resolve().parents[1]

#: The package's modules that define cached compiled functions (paths below PACKAGE_DIR).
JIT_MODULES = (
    "envs/actions.py",
    "envs/fused.py",
    "envs/observation.py",
    "envs/sensors.py",
    "envs/tasks.py",
    "envs/windows.py",
    "physics/failure.py",
    "physics/friction.py",
    "physics/hand.py",
    "physics/kernel.py",
    "physics/model.py",
    "physics/rosenbrock.py",
    "physics/validity.py",
    "quasistatic/solver.py",
)


def sources_digest(paths: tuple[Path, ...] | None = None) -> bytes:
    """SHA-256 (32 bytes) over the names and contents of ``paths`` (default: the
    :data:`JIT_MODULES`), in the given order."""
    if paths is None:
        paths = tuple(PACKAGE_DIR / name for name in JIT_MODULES)
    h = hashlib.sha256()
    for path in paths:
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.digest()


def _in_package(py_file: str) -> bool:
    try:
        return Path(py_file).resolve().is_relative_to(PACKAGE_DIR)
    except (OSError, ValueError):
        return False


def _locator_class(base: Any, default_classes: list[Any], stamp: bytes) -> Any:
    """A numba cache locator class: for a function of this package, numba's own locator
    (the first of ``default_classes`` that accepts it) with the package ``stamp`` as its
    source stamp; other functions are left to ``default_classes``."""

    class PackageStampLocator(base):
        def __init__(self, inner: Any):
            self._inner = inner

        def ensure_cache_path(self) -> None:
            self._inner.ensure_cache_path()

        def get_cache_path(self) -> str:
            return self._inner.get_cache_path()

        def get_source_stamp(self) -> Any:
            return stamp

        def get_disambiguator(self) -> str:
            return self._inner.get_disambiguator()

        @classmethod
        def from_function(cls, py_func: Any, py_file: str) -> Any:
            if not _in_package(py_file):
                return None
            for default in default_classes:
                inner = default.from_function(py_func, py_file)
                if inner is not None:
                    return cls(inner)
            return None

    return PackageStampLocator


def install() -> bool:
    """Put the package stamp in front of numba's cache locators (once). Returns whether it
    is in place."""
    try:
        from numba.core import caching
    except ImportError:
        return False
    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl", None)
    base = getattr(caching, "_CacheLocator", None)
    classes = getattr(impl, "_locator_classes", None)
    if impl is None or base is None or not isinstance(classes, list):
        return False
    if os.environ.get("NUMBA_CACHE_LOCATOR_CLASSES"):
        return False
    if classes and getattr(classes[0], "__name__", "") == "PackageStampLocator":
        return True
    try:
        stamp = sources_digest()
    except OSError:  # a module not readable as a file (e.g. a zipped install)
        return False
    classes.insert(0, _locator_class(base, list(classes), stamp))
    return True


INSTALLED = install()
