"""Benchmarks as a library: the CLI (`pmsm-hil bench`) and scripts call these."""
