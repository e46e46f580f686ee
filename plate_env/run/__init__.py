"""Layer 4, running probes at scale: executors (in-process, a process pool, Ray; :mod:`~plate_env.run.executor`)
and resumable sweeps with JSON-lines records (:mod:`~plate_env.run.sweeps`)."""
