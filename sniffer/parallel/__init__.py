"""Every core: a capture decoded by parts in worker processes, its outputs byte for byte one process's.

    options.py  --jobs N (declared once), its default, and why a command runs in one process after all
    engine.py   the coordinator: reads the capture, hands out parts, takes them back in order
    part.py     one part decoded alone (a worker's work): the cut at a quiet point, the warm-up, the counts
    truth.py    what the coordinator knows for certain at the next cut, and the check a part must pass
    worker.py   the worker process and its pipe
    outputs.py  each output's two halves: a plan (in the workers) and a writer (in the coordinator)
    whole.py    MCAP and Parquet, written by one writer over the whole capture
    run.py      ParallelRun: a run by parts (sniffer.decoding.decode gives it for jobs > 1; a Session's results)
    fleet.py    ingest: a fleet's capture files, one per worker process or per Dask worker

docs/parallel.md says what crosses a cut and why the output is the same.
"""
