"""Where a study's tasks run (docs/guide.md#studies-the-whole-comparison-in-one-command): local worker processes, or a Dask distributed
cluster. Both offer the same small interface — ``submit(fn, arg)`` returning a future,
``wait_first(futures)``, ``close()`` and ``kill()`` — so the runner does not care which.
"""
from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait


def cores() -> int:
    """CPU cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def threads_per_worker(workers: int) -> int:
    """llvmpipe threads per worker so that workers × threads ≤ cores (at least one)."""
    return max(1, cores() // max(1, workers))


def lost_result(exc: BaseException) -> dict:
    """The result of a task whose worker died under it (a crash, the out-of-memory killer, a
    lost Dask worker): a failed run, retried when the study is run again."""
    return {"ok": False, "error": f"the worker process was lost ({type(exc).__name__}: {exc}); "
                                  f"run the study again to retry", "meta": {}, "arrays": {}, "files": {}}


class LocalExecutor:
    """``workers`` spawned processes (a fresh interpreter each: no GL state inherited from the
    parent), each with ``LP_NUM_THREADS`` = ``threads``."""

    description: str

    def __init__(self, workers: int, threads: int | None = None):
        from .tasks import init_worker

        self.workers = workers
        self.threads = threads if threads is not None else threads_per_worker(workers)
        self.pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                                        initializer=init_worker, initargs=(self.threads,))
        self.description = f"{workers} local worker process{'es' if workers > 1 else ''}, " \
                           f"LP_NUM_THREADS={self.threads} each"

    def submit(self, fn, arg):
        """Run ``fn(arg)`` in a worker; a concurrent.futures.Future."""
        return self.pool.submit(fn, arg)

    @staticmethod
    def wait_first(futures) -> set:
        """Block until at least one of ``futures`` is done; the done ones."""
        return wait(futures, return_when=FIRST_COMPLETED).done

    def close(self) -> None:
        """Shut the pool down after its tasks."""
        self.pool.shutdown(wait=True)

    def kill(self) -> None:
        """Stop at once (Ctrl-C): cancel queued tasks and terminate the worker processes."""
        procs = list(getattr(self.pool, "_processes", {}).values())  # no public API for this
        self.pool.shutdown(wait=False, cancel_futures=True)
        for p in procs:
            if p.is_alive():
                p.terminate()
        for p in procs:
            p.join(timeout=5)


class DaskExecutor:
    """Tasks on a running Dask distributed scheduler at ``address`` (``tcp://host:8786``), or on
    a ``distributed.Client`` given directly (tests use a LocalCluster's). Needs the optional
    ``distributed`` extra (``pip install -e '.[dask]'``) and shadowlab installed on the workers."""

    def __init__(self, address):
        try:
            from distributed import Client
        except ImportError as exc:
            raise RuntimeError("--dask needs the 'distributed' package: pip install -e '.[dask]'") from exc
        if isinstance(address, Client):
            self.client, self.own = address, False
        else:
            try:
                self.client, self.own = Client(address, timeout="20s"), True
            except OSError as exc:
                raise RuntimeError(f"cannot reach the Dask scheduler at {address}: {exc}") from exc
        workers = self.client.scheduler_info().get("workers", {})
        self.workers = len(workers)
        self.description = f"Dask cluster at {self.client.scheduler.address} ({self.workers} workers)"

    def submit(self, fn, arg):
        """Run ``fn(arg)`` on the cluster (never deduplicated: ``pure=False``)."""
        return self.client.submit(fn, arg, pure=False)

    @staticmethod
    def wait_first(futures) -> set:
        """Block until at least one of ``futures`` is done; the done ones."""
        from distributed import wait as dask_wait

        return set(dask_wait(list(futures), return_when="FIRST_COMPLETED").done)

    def close(self) -> None:
        """Disconnect (the cluster keeps running)."""
        if self.own:
            self.client.close()

    def kill(self) -> None:
        """Cancel what is still queued, then disconnect."""
        try:
            self.client.cancel(list(self.client.futures.values()) if hasattr(self.client, "futures") else [])
        finally:
            self.close()
