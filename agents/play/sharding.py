"""Episodes split over Ray workers: ``--ray [ADDRESS]`` and ``--ray-workers K`` of the commands.

:func:`map_chunks` is the whole contract: ``map_chunks(fn, chunks, address, workers)`` returns
``[fn(chunk) for chunk in chunks]``, in the order of ``chunks``.

* ``address`` None: in this process, one chunk after the other; Ray is not imported.
* ``address`` :data:`LOCAL` (``"local"``): a Ray instance started on this machine with its
  CPUs (``workers`` CPUs if given); any other string: the address of a running Ray cluster
  as ``ray.init`` takes it (``"auto"``, ``"HOST:6379"``, ``"ray://HOST:10001"``). If Ray is
  already initialised in this process (e.g. by a test) that instance is used as it is.
  Each chunk is one Ray task of one CPU; at most ``workers`` run at once (None: as many as
  the cluster has CPUs).

``fn`` must be a module-level function (Ray sends it by reference: every worker imports its
module, so the workers need the same code, e.g. the same checkout and working directory) and
each chunk plain data: numbers, strings, lists, dicts, frozen dataclasses of these. A task
builds what it needs from that (its env, its policy from a model path or a scripted
policy's name); no env, policy or model object is sent to a worker. ``fn``'s result goes back
the same way (plain data and NumPy arrays). The result of a chunk must depend on the chunk
only (seeded episodes, deterministic play), so that the merged results equal the serial ones
bit for bit: :func:`split` cuts a list into contiguous chunks and :func:`merge` joins the
per-chunk lists again in order.

:func:`add_ray_options` adds ``--ray`` / ``--ray-workers`` to a command's parser and
:func:`ray_options` checks them (Ray importable, worker count in range) before any work:
without Ray installed ``--ray`` is a :class:`~agents.common.cli.UserError` (one line, exit 2).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

from agents.common.cli import UserError, check_range

_Chunk = TypeVar("_Chunk")
_Result = TypeVar("_Result")

#: ``--ray`` without an address: a Ray instance started here (``ray.init(address="local")``).
LOCAL = "local"
#: Most Ray tasks a command runs at once.
MAX_WORKERS = 1024
#: The install hint of the missing-Ray error.
INSTALL_HINT = "pip install 'softhand-env[ray]'"


@dataclass(frozen=True)
class RayOptions:
    """``--ray`` / ``--ray-workers`` of a command line: ``address`` (None: no Ray, serial;
    :data:`LOCAL` or a cluster address) and ``workers`` (None: one per CPU of the cluster)."""

    address: str | None = None
    workers: int | None = None


def add_ray_options(parser: argparse.ArgumentParser) -> None:
    """Add ``--ray [ADDRESS]`` and ``--ray-workers K`` to ``parser``."""
    parser.add_argument("--ray", nargs="?", const=LOCAL, default=None, metavar="ADDRESS",
                        help="split the episodes over Ray workers: without ADDRESS a Ray "
                             "started here with this machine's CPUs, else a running "
                             "cluster's address (auto, HOST:6379, ray://HOST:10001); results "
                             "equal the serial run's")
    parser.add_argument("--ray-workers", type=int, default=None, metavar="K",
                        help=f"with --ray: Ray tasks (chunks of episodes), 1 .. {MAX_WORKERS} "
                             "(default: the cluster's CPUs)")


def ray_options(address: str | None, workers: int | None) -> RayOptions:
    """The checked :class:`RayOptions` of ``--ray`` / ``--ray-workers``: :class:`UserError`
    for ``--ray-workers`` without ``--ray`` or out of range, and for ``--ray`` without Ray
    (nothing is started here)."""
    if workers is not None:
        if address is None:
            raise UserError("--ray-workers needs --ray")
        check_range("--ray-workers", workers, 1, MAX_WORKERS)
    if address is not None:
        if not address.strip():
            raise UserError("--ray: the address is empty")
        require_ray()
    return RayOptions(address, workers)


def require_ray(flag: str = "--ray", hint: str = INSTALL_HINT) -> Any:
    """The ``ray`` module, or :class:`UserError` naming ``flag`` (with the install ``hint``)
    if it is missing."""
    try:
        import ray
    except ImportError:
        raise UserError(f"{flag} needs Ray, which is not installed ({hint})") from None
    return ray


def split(items: Sequence[_Chunk], n: int) -> list[list[_Chunk]]:
    """``items`` cut into ``min(n, len(items))`` contiguous chunks whose lengths differ by at
    most one (earlier chunks the longer ones); ``merge(split(items, n)) == list(items)``."""
    n = max(1, min(n, len(items)))
    size, extra = divmod(len(items), n)
    out, start = [], 0
    for k in range(n):
        stop = start + size + (k < extra)
        out.append(list(items[start:stop]))
        start = stop
    return out


def merge(results: Sequence[Sequence[_Result]]) -> list[_Result]:
    """The per-chunk result lists joined in chunk order."""
    return [r for chunk in results for r in chunk]


def cluster_cpus(address: str, workers: int | None = None, flag: str = "--ray") -> int:
    """Connect to (or start, :data:`LOCAL`) Ray unless it is initialised; returns the CPUs of
    the cluster (at least 1). A local instance gets ``workers`` CPUs if given, else all of
    this machine's; no dashboard. The one place the commands call ``ray.init`` (also for
    ``agents.rllib_train --address``); ``flag`` names the option in the error of an address
    with no cluster."""
    ray = require_ray(flag)
    if not ray.is_initialized():
        kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": True}
        if address == LOCAL:
            kwargs["num_cpus"] = workers
        try:
            ray.init(address=address, **kwargs)
        except ConnectionError as exc:
            raise UserError(f"{flag} {address}: no Ray cluster there ({exc})") from None
    return max(1, math.floor(ray.cluster_resources().get("CPU", 1)))


def worker_count(options: RayOptions, n_items: int) -> int:
    """Chunks to cut ``n_items`` episodes into: 1 without Ray, else ``--ray-workers`` or the
    cluster's CPUs (Ray started or joined here), never more than ``n_items``."""
    if options.address is None:
        return 1
    workers = options.workers or cluster_cpus(options.address, options.workers)
    return max(1, min(workers, n_items))


def map_chunks(fn: Callable[[_Chunk], _Result], chunks: Sequence[_Chunk],
               address: str | None = None, workers: int | None = None) -> list[_Result]:
    """``[fn(c) for c in chunks]``, serially (``address`` None) or as Ray tasks of one CPU each,
    at most ``workers`` at once (None: as many as the cluster's CPUs); see the module doc for
    ``address`` and for what ``fn`` and the chunks must be. A failure of a task is raised here
    as the task's own exception."""
    if address is None:
        return [fn(c) for c in chunks]
    ray = require_ray()
    cpus = cluster_cpus(address, workers)
    limit = max(1, min(workers or cpus, len(chunks) or 1))
    task = ray.remote(num_cpus=1, max_retries=0)(fn)
    pending: dict[Any, int] = {}
    results: dict[int, Any] = {}
    queue = list(enumerate(chunks))
    while queue or pending:
        while queue and len(pending) < limit:
            k, chunk = queue.pop(0)
            pending[task.remote(chunk)] = k
        done, _ = ray.wait(list(pending), num_returns=1)
        for ref in done:
            k = pending.pop(ref)
            try:
                results[k] = ray.get(ref)
            except ray.exceptions.RayTaskError as exc:  # the task's exception, e.g. UserError
                if isinstance(getattr(exc, "cause", None), Exception):
                    raise exc.cause from None
                raise
    return [results[k] for k in range(len(chunks))]
