"""A fleet's captures into a dataset with every core, or a Dask cluster: each capture decoded on its own.

    for result in take_in_all(ds, files, spec, known, link=None, jobs=4):        # worker processes
    for result in take_in_all(ds, files, spec, known, link=None, dask="tcp://scheduler:8786"):
        print(result.line())                                                     # Taken | Skipped | Failed

A capture file of a fleet dataset is one unit of work already (sniffer.dataset.ingest:
prepare, stage, commit): this process checks the manifest, hashes the file and makes
its staging folder (`prepare`), a worker decodes it into that folder (`stage`, plain
data in and out), and this process takes the staged files in (`commit`), in the order
the files were given.  So the dataset is the one a single process makes: the same
rows in the same files, the same manifest entries (a file identical to one taken in
earlier in the run is skipped at its commit, as it is in one process).  At most
twice as many captures as workers are staged at a time.

With Dask the workers must see the captures and the dataset at the same paths (a
shared file system): a worker reads the capture and writes the staging folder, this
process moves the files in.
"""

from __future__ import annotations

from collections import deque


def _local(jobs: int):
    import multiprocessing
    import os
    from concurrent.futures import ProcessPoolExecutor

    from sniffer.processes.parent_death import worker_args, worker_ends_with_parent

    ctx = multiprocessing.get_context("fork" if hasattr(os, "fork") else "spawn")
    # the pool starts its workers at the first submit, from this thread: a killed ingest leaves none behind
    pool = ProcessPoolExecutor(max_workers=jobs, mp_context=ctx, initializer=worker_ends_with_parent,
                               initargs=worker_args())
    return pool, lambda job: pool.submit(_stage, job), jobs, pool.shutdown


DASK_PORT = 8786
MAX_HANDSHAKE = 1 << 20  # a scheduler's first message (its handshake) is a few hundred bytes


def dask_address(text: str) -> str:
    """The scheduler's address, checked before any connection: parsed (InputError, one line, for a malformed
    one), then its first 8 bytes read with a connect and a reply timeout.  A scheduler speaks first: the length
    of its handshake.  A port that says nothing, or answers otherwise (an HTTP server's "HTTP/1.1" read as a
    length would be an allocation of exabytes), is refused here, not handed to distributed."""
    from sniffer.inputs import InputError, parse_address, probe

    addr = parse_address(text, "--dask", ("tcp",), default_port=DASK_PORT)
    first = probe(addr, "--dask", reply=8)
    if int.from_bytes(first, "little") > MAX_HANDSHAKE:
        raise InputError(f"--dask {addr}: answers as no Dask scheduler does (it began with {first!r})")
    return str(addr)


def _dask(address: str):
    try:
        from distributed import Client
    except ImportError:
        raise RuntimeError("--dask needs dask[distributed] (pip install 'dask[distributed]')") from None
    address = dask_address(address)
    try:
        client = Client(address, timeout=10)
    except (OSError, ValueError) as e:
        raise RuntimeError(f"--dask {address}: cannot reach the scheduler: {str(e)[:200]}") from None
    workers = max(1, sum(w.get("nthreads", 1) for w in client.scheduler_info().get("workers", {}).values()))
    return client, lambda job: client.submit(_stage, job, pure=False), workers, client.close


def _stage(job: dict) -> dict:
    from sniffer.dataset.ingest import stage

    return stage(job)


class DaskError(RuntimeError):
    """The Dask cluster cannot be used (not installed, not reachable): one line."""


def take_in_all(ds, files: list[str], spec, known, *, link: str | None, jobs: int = 1, dask: str | None = None):
    """Each file as take_in would, staged by `jobs` worker processes or by the Dask cluster at `dask`; the results
    in the order of `files` (see the module doc)."""
    from sniffer.dataset.ingest import Prepared, commit, prepare

    try:
        _, submit, width, shutdown = _dask(dask) if dask else _local(jobs)
    except RuntimeError as e:
        raise DaskError(str(e)) from None
    waiting: deque = deque()  # (prepared or result, future or None), in file order
    todo = iter(files)
    try:
        while True:
            while len([w for w in waiting if w[1] is not None]) < 2 * width:
                path = next(todo, None)
                if path is None:
                    break
                got = prepare(ds, path, known)
                waiting.append((got, submit(got.job(spec, link)) if isinstance(got, Prepared) else None))
            if not waiting:
                return
            got, future = waiting.popleft()
            if future is None:
                yield got
                continue
            try:
                staged = future.result()
            except Exception as e:  # noqa: BLE001 - a worker lost: the capture is not taken in, said
                staged = {"why": f"{got.path}: its worker failed: {type(e).__name__}: {e}"}
            yield commit(ds, got, staged, known)
    finally:
        for got, future in waiting:  # interrupted: what was staged is removed, nothing taken in
            if future is not None:
                future.cancel()
            if isinstance(got, Prepared):
                commit_nothing(ds, got)
        shutdown()


def commit_nothing(ds, prepared) -> None:
    """A prepared capture given up (the run was interrupted): its staging folder removed."""
    from sniffer.dataset.ingest import release

    release(ds, prepared.staging, prepared.lock)
