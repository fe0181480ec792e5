"""The one parallel map of the project: serial, local processes, or a dask.distributed cluster.

The design search's beams and exact re-scorings and the Monte Carlo's trials all go
through :func:`map_jobs`; each job is computed the same way wherever it runs, so the
answer does not depend on ``workers`` or ``scheduler``.
"""

from __future__ import annotations

import contextlib
from concurrent.futures import ProcessPoolExecutor

from calib.errors import CalibError

# The local pools of the enclosing :func:`worker_pool` blocks, by worker count (none outside one).
_shared: dict[int, ProcessPoolExecutor] = {}


@contextlib.contextmanager
def worker_pool(workers: int):
    """Keep one pool of ``workers`` local processes for every :func:`map_jobs` inside.

    A design maps its exact-scoring jobs in many small rounds (the screen reports as it
    goes, the box re-scores two at a time); a pool per round pays the workers' start and
    their imports (numba's and its compiled kernels' 0.5-1 s under a Gauss-Markov profile)
    each time. Nested uses share the outermost pool; serial runs (``workers`` <= 1) need none.
    """
    if workers <= 1 or workers in _shared:
        yield
        return
    with ProcessPoolExecutor(max_workers=workers) as pool:
        _shared[workers] = pool
        try:
            yield
        finally:
            del _shared[workers]


def map_jobs(fn, jobs, workers: int = 1, scheduler: str | None = None, done=None):
    """Run jobs serially, on local processes, or on a dask.distributed cluster; same order out.

    ``done(n)``, if given, is called as the first ``n`` results are in (serially and on local
    processes as each arrives in order; on a cluster once, at the end).
    """
    if scheduler:
        try:
            from dask.distributed import Client
        except ImportError:
            raise CalibError(
                "--scheduler needs dask.distributed", "--scheduler", "pip install 'seqdesign[dask]'"
            ) from None
        client = scheduler if not isinstance(scheduler, str) else Client(scheduler)
        try:
            return _collect(client.gather(client.map(fn, jobs, pure=False)), done)
        finally:
            if isinstance(scheduler, str):
                client.close()
    if workers > 1:
        if workers in _shared:
            return _collect(_shared[workers].map(fn, jobs), done)
        with ProcessPoolExecutor(max_workers=workers) as pool:
            return _collect(pool.map(fn, jobs), done)
    return _collect(map(fn, jobs), done)


def _collect(results, done) -> list:
    """The results as a list, saying each arrival to ``done`` (the executors yield them in order)."""
    out = []
    for result in results:
        out.append(result)
        if done is not None:
            done(len(out))
    return out
