"""sphnl's Python harness, shared by experiments/, plots/ and tools/.

    results  the results format (docs/CONTRACTS.md): experiment files,
             benchmark names, Google Benchmark JSON -> pandas rows
    fsio     write_atomic, the one way any script writes an output file
    valgrind the build valgrind can run, cache models, callgrind commands and
             output parsing (make compare, the counters kind)

Scripts import it as `harness.<module>` and are run as modules from the
repository root (`/usr/bin/python3 -m experiments.run ...`,
`/usr/bin/python3 -m plots.report ...`), which puts the root on sys.path;
from elsewhere set PYTHONPATH to the repository root.
"""
