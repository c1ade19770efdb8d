"""The one way the project runs many FEM solves: tasks on Dask.

Without a scheduler address, a ``distributed.LocalCluster`` of worker processes (one thread
and one BLAS thread each: a sparse factorisation on two BLAS threads beside another solve
only fights it for the two cores) sized to the machine; with one, the user's cluster. One
local worker runs the tasks in this process instead: no cluster to start (~2 s) and the
solve's own progress reaches the caller.

Results come back as they finish (:func:`run` is a generator), so a caller can cache each one
at once: Ctrl-C then keeps everything finished, and a rerun resumes. A task's exception is
returned with its result, not raised, so one failed solve never ends a batch.

It belongs to the model, not to the design studies above it: the model's own calibration
grid and wrench paths (``physics/array_grid.py``) solve their load paths through it, and the
model never imports ``studies/``.
"""

from __future__ import annotations

import contextlib
import logging
import os
import queue
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import PhysicsError

Progress = Callable[[float, str], None]
BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
#: How long to wait for a named scheduler to answer before saying it is unreachable.
CONNECT_TIMEOUT_S = 15


class BatchError(PhysicsError):
    """The cluster could not be reached or started (a user's address or setup)."""


@dataclass(frozen=True)
class TaskResult:
    """One task's outcome: its index in the batch, value or error, where and how long."""

    index: int
    value: Any
    error: BaseException | None
    worker: str
    seconds: float


def default_workers() -> int:
    """The cores this process may use (a container's limit, not the host's count)."""
    with contextlib.suppress(AttributeError):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return str(get_worker().address)
    except (ImportError, ValueError):
        return "local"


def call(fn: Callable[..., Any], args: tuple[Any, ...],
         progress: Progress | None = None) -> tuple[Any, BaseException | None, str, float]:
    """Run ``fn(*args, progress)`` and return (value, error, worker, seconds), never raising."""
    start = time.perf_counter()
    worker = _worker_name()
    try:
        value = fn(*args, progress)
    except Exception as err:  # the caller decides what a failure means
        return None, err, worker, time.perf_counter() - start
    return value, None, worker, time.perf_counter() - start


def _remote(fn: Callable[..., Any], args: tuple[Any, ...], topic: str, index: int
            ) -> tuple[Any, BaseException | None, str, float]:
    """:func:`call` on a Dask worker, its progress sent to the client as events."""
    from distributed import get_worker

    worker = get_worker()

    def report(fraction: float, message: str) -> None:
        worker.log_event(topic, [index, float(fraction), str(message)])

    return call(fn, args, report)


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """Spawned workers inherit the environment: one BLAS thread each, as many as cores."""
    saved = {k: os.environ.get(k) for k in BLAS_THREADS}
    os.environ.update(dict.fromkeys(BLAS_THREADS, "1"))
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


@contextlib.contextmanager
def client(scheduler: str | None, workers: int) -> Iterator[Any]:
    """A Dask client: of the cluster at ``scheduler``, or of a new local one (closed after)."""
    import dask
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            c = Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s")
        except (OSError, TimeoutError, ValueError) as err:
            raise BatchError(f"cannot reach the Dask scheduler at {scheduler} ({err}); start "
                             "one with 'dask scheduler' and 'dask worker', or drop "
                             "--scheduler to run locally.") from None
        try:
            yield c
        finally:
            c.close()
        return
    environ = dict.fromkeys(BLAS_THREADS, 1)
    with one_blas_thread(), dask.config.set({"distributed.nanny.pre-spawn-environ":
                                             {"MALLOC_TRIM_THRESHOLD_": 65536, **environ}}):
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=logging.ERROR)
    try:
        with Client(cluster) as c:
            yield c
    finally:
        cluster.close()


def run(fn: Callable[..., Any], args: Sequence[tuple[Any, ...]], *,
        scheduler: str | None = None, workers: int | None = None,
        costs: Sequence[float] | None = None, progress: Progress | None = None,
        label: str = "task") -> Iterator[TaskResult]:
    """Yield ``fn(*a, progress)`` for each ``a`` in ``args`` as it finishes (any order).

    ``fn`` takes a last argument ``progress(fraction, message)`` (or None) for its own
    progress, and it and its arguments must be picklable and importable on the workers.
    ``costs`` (relative run times) order the work, longest first, and weight the progress;
    the caller's ``progress`` hears each task's own messages and "label k/n done, ~T s left"
    after each task.
    """
    n = len(args)
    if n == 0:
        return
    weights = np.array([float(c) for c in costs] if costs is not None else [1.0] * n)
    weights = np.where(weights > 0, weights, 1.0)
    order = [int(i) for i in np.argsort(-weights, kind="stable")]
    workers = workers if workers is not None else default_workers()
    started = time.perf_counter()
    done = np.zeros(n)
    count = 0

    def fraction() -> float:
        return float(done @ weights / weights.sum())

    def step(index: int, f: float, message: str) -> None:
        done[index] = max(done[index], min(1.0, f))
        if progress is not None:
            progress(fraction(), f"{label} {index + 1}/{n}: {message}")

    def tell(result: TaskResult) -> TaskResult:
        nonlocal count
        done[result.index] = 1.0
        count += 1
        if progress is not None:
            elapsed = time.perf_counter() - started
            share = fraction()
            left = elapsed * (1.0 - share) / share
            progress(share, f"{label}s {count}/{n} done, ~{left:.0f} s left "
                     f"({elapsed:.0f} s so far)")
        return result

    if scheduler is None and workers <= 1:
        for i in order:
            inner = (lambda f, m, i=i: step(i, f, m)) if progress is not None else None
            yield tell(TaskResult(i, *call(fn, args[i], inner)))
        return
    from distributed import as_completed

    topic = f"tactile-progress-{os.getpid()}-{started}"
    events: queue.Queue[Any] = queue.Queue()
    with client(scheduler, workers) as c:
        c.subscribe_topic(topic, events.put)
        futures = {}
        for rank, i in enumerate(order):
            futures[c.submit(_remote, fn, args[i], topic, i, key=f"{label}-{i}-{topic}",
                             pure=False, priority=n - rank)] = i
        pending = as_completed(futures)
        try:
            while not pending.is_empty():
                with contextlib.suppress(queue.Empty):
                    _, (index, f, message) = events.get(timeout=0.25)
                    step(int(index), float(f), str(message))
                for future in pending.next_batch(block=False):
                    try:
                        value, error, worker, seconds = future.result()
                    except Exception as err:  # e.g. the worker died
                        value, error, worker, seconds = None, err, "lost", 0.0
                    yield tell(TaskResult(futures[future], value, error, worker, seconds))
        finally:
            with contextlib.suppress(Exception):
                c.unsubscribe_topic(topic)
            c.cancel(list(futures))
