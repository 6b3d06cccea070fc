"""One freshness stamp for numba's on-disk caches of the package's compiled functions.

numba keeps a compiled function (``@njit(cache=True)``) on disk and reuses it while the source
file that defines it is unchanged. A compiled function also contains the code of the compiled
functions it calls from *other* modules: after an edit of ``rosenbrock.py`` alone, the cached
control step of ``envs/fused.py`` would still run the old integrator. This module gives every
cached function of the package one stamp instead of its own file's, the SHA-256 of all the
package's modules that define cached functions (:data:`JIT_MODULES`), so that an edit of any of
them recompiles all of them. Paths, file names and everything else of the cache stay numba's.

numba's own index update is not safe between processes: to save a new compiled version it
reads the index, takes the lowest unused data-file number, writes the index and then the data
file, so two processes compiling different versions of one function at the same time can both
take number 1 and leave an index entry that names the other's machine code (run, it crashes the
interpreter). For this package's functions :func:`install` replaces that step
(:func:`_safe_save`): the data file gets a unique name and is written whole before the index
names it, and the index is re-read and rewritten under a file lock (``fcntl``; without it a
concurrent update can be lost, which costs a recompilation, never a wrong entry); data files
no index entry names are removed once they are :data:`ORPHAN_AGE_S` old.

Importing this module installs the stamp (:func:`install`); each module in
:data:`JIT_MODULES` imports it before its first decorator, since numba chooses a function's
cache when the decorator runs. Installing does nothing where numba's cache internals differ
from those this was written against (numba 0.68's ``CacheImpl._locator_classes``; earlier
releases name the class ``_CacheImpl``), or when ``NUMBA_CACHE_LOCATOR_CLASSES`` chooses the
cache classes: caching then works as numba's default.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import time
import uuid
from collections.abc import Iterator
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


#: Age (s) after which a data file no index entry names is removed (a younger one may belong to
#: a save of another process that has not updated the index yet).
ORPHAN_AGE_S = 600.0


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


@contextlib.contextmanager
def _index_lock(index_path: str) -> Iterator[None]:
    """An exclusive lock (``fcntl.flock`` on ``<index>.lock``) around an index update; no
    lock where ``fcntl`` is missing or the lock file cannot be opened."""
    try:
        import fcntl
        handle = open(index_path + ".lock", "a+b")  # noqa: SIM115  (closed below)
    except (ImportError, OSError):
        yield
        return
    try:
        fcntl.flock(handle, fcntl.LOCK_EX)
        yield
    finally:
        handle.close()  # releases the lock


def _safe_save(cache_file: Any, key: Any, data: Any) -> None:
    """Save a compiled version ``data`` under ``key`` in numba's ``IndexDataCacheFile``
    ``cache_file`` (module doc): a data file of a unique name written whole, then the index
    re-read, updated and written under :func:`_index_lock`, then the data files of this
    function that the index does not name and that are older than :data:`ORPHAN_AGE_S`
    removed (best effort)."""
    base = cache_file._index_name[: -len(".nbi")]
    name = f"{base}.{uuid.uuid4().hex[:16]}.nbc"
    cache_file._save_data(name, data)
    with _index_lock(cache_file._index_path):
        overloads = cache_file._load_index()
        overloads[key] = name
        cache_file._save_index(overloads)
        named = set(overloads.values())
        oldest = time.time() - ORPHAN_AGE_S  # younger files may be another save in flight
        with contextlib.suppress(OSError):
            for entry in os.scandir(cache_file._cache_path):
                with contextlib.suppress(OSError):  # removed by another process meanwhile
                    if (entry.name.startswith(base + ".") and entry.name.endswith(".nbc")
                            and entry.name not in named and entry.stat().st_mtime < oldest):
                        os.remove(entry.path)


def _install_safe_save(caching: Any, stamp: bytes) -> bool:
    """Route the saves of the package's cache entries (those with the package ``stamp``)
    through :func:`_safe_save`; other functions keep numba's ``save``. False where numba's
    ``IndexDataCacheFile`` lacks what :func:`_safe_save` uses."""
    cls = getattr(caching, "IndexDataCacheFile", None)
    needed = ("save", "_load_index", "_save_index", "_save_data")
    if cls is None or not all(hasattr(cls, name) for name in needed):
        return False
    if getattr(cls.save, "safe_for", None) is not None:
        return True
    numba_save = cls.save

    def save(self: Any, key: Any, data: Any) -> None:
        mine = getattr(self, "_source_stamp", None) == stamp and all(
            hasattr(self, name) for name in ("_index_name", "_index_path", "_cache_path"))
        if mine:
            _safe_save(self, key, data)
        else:
            numba_save(self, key, data)

    save.safe_for = stamp  # type: ignore[attr-defined]
    cls.save = save
    return True


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
    _install_safe_save(caching, stamp)
    return True


INSTALLED = install()
