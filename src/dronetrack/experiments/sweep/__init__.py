"""Parameter sweeps: a grid of runs on local processes or a Dask cluster, with results
streamed to ``results.jsonl`` (``dronetrack sweep``) and a report (``sweep-report``)."""
