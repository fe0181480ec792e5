"""The one parallel map of the project: serial, local processes, or a dask.distributed cluster.

The design search's beams and exact re-scorings and the Monte Carlo's trials all go
through :func:`map_jobs`; each job is computed the same way wherever it runs, so the
answer does not depend on ``workers`` or ``scheduler``.
"""

from __future__ import annotations

from calib.errors import CalibError


def map_jobs(fn, jobs, workers: int = 1, scheduler: str | None = None):
    """Run jobs serially, on local processes, or on a dask.distributed cluster; same order out."""
    if scheduler:
        try:
            from dask.distributed import Client
        except ImportError:
            raise CalibError(
                "--scheduler needs dask.distributed", "--scheduler", "pip install 'seqdesign[dask]'"
            ) from None
        client = scheduler if not isinstance(scheduler, str) else Client(scheduler)
        try:
            return client.gather(client.map(fn, jobs, pure=False))
        finally:
            if isinstance(scheduler, str):
                client.close()
    if workers > 1:
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(max_workers=workers) as pool:
            return list(pool.map(fn, jobs))
    return [fn(j) for j in jobs]
