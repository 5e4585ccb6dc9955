"""The Dask backend of :func:`activetrack.montecarlo.parallel_map`: seeded tasks on a cluster.

``parallel_map(fn, tasks, scheduler="tcp://host:8786")`` sends the tasks to the workers of a
running Dask distributed scheduler (docs/dask.md) in the local pool's chunks
(:func:`~activetrack.montecarlo.chunks.even_chunks`, four per worker thread), each one pickled
payload whose results come back in task order, bit-identical to ``jobs=1``.

A worker of another host shares no forked state, so each payload carries the client's
registrations (sensor kinds, filters, criteria: a ``__main__`` plugin travels by value, a
module's must be importable on the worker), the versions of :data:`PINNED` (a worker whose
versions differ refuses the chunk) and whether the client tuned the allocator (docs/dask.md,
"What travels with the tasks"). The payload is unpickled inside the task, so these failures
come back as one :class:`WorkerSetupError` rather than as the scheduler's failure to read the
task graph; only activetrack itself must be importable on the scheduler.
"""

from __future__ import annotations

import os
import socket
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from importlib import metadata
from typing import TYPE_CHECKING, Any, TypeAlias, cast
from urllib.parse import urlsplit

from activetrack.montecarlo.chunks import even_chunks

if TYPE_CHECKING:
    from distributed import Client

__all__ = [
    "SCHEMES",
    "Scheduler",
    "SchedulerError",
    "WorkerSetupError",
    "check_scheduler",
    "connected",
    "dask_map",
]

# A scheduler's address ("tcp://host:port") or a connected distributed.Client.
Scheduler: TypeAlias = "str | Client"

# The address schemes of distributed's transports (inproc: a cluster in this process).
SCHEMES = ("tcp", "tls", "ws", "wss", "ucx", "inproc")
_SOCKET_SCHEMES = ("tcp", "tls", "ws", "wss")
PROBE_TIMEOUT_S = 3.0  # the first TCP connection to the scheduler (fails fast when refused)
CONNECT_TIMEOUT_S = 10.0  # the Dask client's connection
WORKER_WAIT_S = 30.0  # a scheduler without workers: how long to wait for the first one
# The distributions whose versions fix the numbers: they must match between client and worker
# (numba and llvmlite compile the planner's kernels, which agree with numpy to round-off only).
PINNED = ("activetrack", "numpy", "scipy", "numba", "llvmlite")


class SchedulerError(ValueError):
    """The scheduler address is malformed, nothing answers there, or no worker joined it."""


class WorkerSetupError(RuntimeError):
    """A worker cannot run the tasks as the client would: a module or version differs."""


def check_scheduler(address: str) -> str:
    """``address`` if it is a scheduler address (``scheme://host:port``, a scheme of
    :data:`SCHEMES`; ``host:port`` means tcp) that answers, else a :class:`SchedulerError`. For
    TCP transports a plain connection is tried first, so a refused address fails at once."""
    if not isinstance(address, str) or not address.strip():
        raise SchedulerError(f"scheduler: must be an address like tcp://host:8786, got {address!r}")
    text = address.strip()
    if "://" not in text:
        text = f"tcp://{text}"
    parts = urlsplit(text)
    if parts.scheme not in SCHEMES:
        raise SchedulerError(
            f"scheduler: the scheme must be one of {SCHEMES} (tcp://host:port), got {address!r}"
        )
    if parts.scheme in _SOCKET_SCHEMES:
        _probe(address, *_host_port(address, parts))
    return text


def _host_port(address: str, parts: Any) -> tuple[str, int]:
    try:
        port = parts.port
    except ValueError:
        port = None
    if not parts.hostname or not port or parts.path not in ("", "/"):
        raise SchedulerError(
            f"scheduler: must be scheme://host:port with a port in [1, 65535], got {address!r}"
        )
    return parts.hostname, port


def _probe(address: str, host: str, port: int) -> None:
    try:
        with socket.create_connection((host, port), timeout=PROBE_TIMEOUT_S):
            pass
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise SchedulerError(
            f"scheduler: cannot reach a Dask scheduler at {address} ({reason}): start one with "
            "`dask scheduler` and pass the address it prints (docs/dask.md)"
        ) from None


@contextmanager
def connected(scheduler: Scheduler | None) -> Iterator[Scheduler | None]:
    """``with connected(scheduler) as s:`` one connection for several maps: an address becomes
    a ``distributed.Client``, closed at the end; None and a Client are handed on as they are."""
    if scheduler is None or not isinstance(scheduler, str):
        yield scheduler
        return
    from distributed import Client

    address = check_scheduler(scheduler)
    try:
        client = Client(address, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
    except OSError as exc:
        raise SchedulerError(f"scheduler: cannot connect to {scheduler}: {exc}") from None
    with client:
        yield client


def dask_map(fn: Callable[[Any], Any], tasks: Sequence[Any], scheduler: Scheduler) -> Iterator[Any]:
    """``fn(t)`` of every task, in task order, computed on the cluster of ``scheduler`` (an
    address or a connected ``distributed.Client``). A task's exception is raised here."""
    with connected(scheduler) as client:
        yield from _map_on(cast("Client", client), fn, tasks)


def _map_on(client: Client, fn: Callable[[Any], Any], tasks: Sequence[Any]) -> Iterator[Any]:
    from distributed.protocol.pickle import dumps

    context = client_context()
    chunks = even_chunks(tasks, _worker_threads(client))
    payloads = [dumps((fn, chunk, context)) for chunk in chunks]
    futures = client.map(run_chunk, payloads, pure=False)
    try:
        for future in futures:
            yield from future.result()
    finally:
        client.cancel(futures)


def _worker_threads(client: Client) -> int:
    """The cluster's worker threads, after waiting up to WORKER_WAIT_S for a first worker."""
    if not client.nthreads():
        try:
            client.wait_for_workers(1, timeout=WORKER_WAIT_S)
        except TimeoutError:
            where = getattr(client.scheduler, "address", "the scheduler")
            raise SchedulerError(
                f"scheduler: no worker joined {where} within "
                f"{WORKER_WAIT_S:g} s: start `dask worker ADDRESS` on each host (docs/dask.md)"
            ) from None
    return max(1, sum(client.nthreads().values()))


# --- what travels with the tasks ----------------------------------------------------------------


@dataclass(frozen=True)
class Registrations:
    """The client's registries: sensor kinds, filters and planner criteria (with built-ins)."""

    sensors: tuple[Any, ...]  # scenarios.registry.SensorKind
    filters: tuple[Any, ...]  # filters.registry.FilterKind
    criteria: tuple[Any, ...]  # planning.criteria.Criterion


@dataclass(frozen=True)
class ClientContext:
    """What every chunk carries besides its tasks (module docstring)."""

    registrations: Registrations
    versions: dict[str, str]  # python and PINNED distributions
    allocator_tuned: bool  # activetrack.allocator.tune_allocator applied in the client


def client_context() -> ClientContext:
    """This process's :class:`ClientContext`."""
    from activetrack.allocator import allocator_tuned
    from activetrack.filters.registry import filter_kind, filter_names
    from activetrack.planning.criteria import criteria
    from activetrack.scenarios.registry import registered_kinds, sensor_kind

    registrations = Registrations(
        sensors=tuple(sensor_kind(k) for k in registered_kinds()),
        filters=tuple(filter_kind(n) for n in filter_names()),
        criteria=criteria(),
    )
    return ClientContext(registrations, _versions(), allocator_tuned())


def _versions() -> dict[str, str]:
    """Python's and the :data:`PINNED` distributions' versions in this process."""
    found = {"python": ".".join(map(str, sys.version_info[:3]))}
    for name in PINNED:
        try:
            found[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            found[name] = "not installed"
    return found


_INSTALL = threading.Lock()  # a worker's threads may install the same registrations at once


def run_chunk(payload: bytes) -> list[Any]:
    """On a worker: unpickle one chunk ``(fn, tasks, ClientContext)``, check the versions,
    install the client's registrations and settings and return ``[fn(t) for t in tasks]``.
    Module-level, so the scheduler holds it by name."""
    from distributed.protocol.pickle import loads

    from activetrack.allocator import tune_allocator

    try:
        fn, tasks, context = loads(payload)
    except (ImportError, AttributeError) as exc:
        raise WorkerSetupError(
            f"worker {socket.gethostname()}: cannot load the tasks ({type(exc).__name__}: "
            f"{exc}): install the module that defines the tasks' function or a registered "
            "plugin (sensor kind, filter, criterion) on every worker host (docs/dask.md)"
        ) from None
    mine = _versions()
    differ = {k: (v, mine.get(k)) for k, v in context.versions.items() if mine.get(k) != v}
    if differ:
        shown = ", ".join(f"{k} {c} on the client, {w} here" for k, (c, w) in differ.items())
        raise WorkerSetupError(
            f"worker {socket.gethostname()}: {shown}; every host needs the same pinned "
            "versions (make setup) for identical results (docs/dask.md)"
        )
    with _INSTALL:
        _install(context.registrations)
    if context.allocator_tuned:
        tune_allocator(ignore=_dask_environ())
    return [fn(t) for t in tasks]


def _dask_environ() -> tuple[str, ...]:
    """The variables of this process that hold the values Dask's nanny sets before it starts a
    worker (``distributed.nanny.pre-spawn-environ``): Dask's defaults, not the user's."""
    import dask.config

    preset = dask.config.get("distributed.nanny.pre-spawn-environ", default={}) or {}
    return tuple(k for k, v in preset.items() if os.environ.get(k) == str(v))


def _install(reg: Registrations) -> None:
    """Register on this worker what the client had registered and this worker lacks or has
    otherwise. Built-ins are the same on both sides and are left alone."""
    from activetrack.filters.registry import filter_kind as current_filter
    from activetrack.filters.registry import filter_names, register_filter
    from activetrack.planning.criteria import criterion_names, get_criterion, register_criterion
    from activetrack.scenarios.registry import (
        register_sensor,
        registered_kinds,
        sensor_kind,
        unregister_sensor,
    )

    current = {name: sensor_kind(name) for name in registered_kinds()}
    for entry in reg.sensors:
        now = current.get(entry.kind)
        if now is not None:
            if (now.sensor_class, now.config_class) == (entry.sensor_class, entry.config_class):
                continue
            unregister_sensor(entry.kind)
        register_sensor(entry.sensor_class, entry.config_class, build=entry.build)
    for entry in reg.filters:
        if entry.name not in filter_names() or current_filter(entry.name) != entry:
            _unless_built_in(register_filter, entry.name, entry.factory,
                             particle_based=entry.particle_based,
                             description=entry.description, replace=True)  # fmt: skip
    for criterion in reg.criteria:
        if criterion.name not in criterion_names() or get_criterion(criterion.name) != criterion:
            _unless_built_in(register_criterion, criterion, replace=True)


def _unless_built_in(register: Callable[..., Any], *args: Any, **kwargs: Any) -> None:
    """``register(*args, **kwargs)``; a built-in name refuses (ValueError) and keeps its own
    entry, the same on client and worker (its functions only travelled by value)."""
    try:
        register(*args, **kwargs)
    except ValueError:
        pass
