"""Benchmarks of the measurement core (not part of ``make test``): ``make bench``."""
