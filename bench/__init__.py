"""Benchmarks and evaluations of emotive: run as ``python -m bench.run`` (``make bench``)."""
