"""Speed and accuracy measurements. Each module answers one question and writes
``docs/img/<name>.png`` and ``docs/bench/<name>.md``; ``python -m benchmarks.all``
runs them all and assembles ``docs/BENCHMARKS.md``."""
