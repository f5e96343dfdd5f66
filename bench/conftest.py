"""Benchmarks run with pytest-benchmark: ``python -m pytest bench --benchmark-only``."""

import os

os.environ.setdefault("MPLBACKEND", "Agg")
