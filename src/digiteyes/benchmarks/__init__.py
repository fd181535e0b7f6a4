"""Benchmarks behind ``digiteyes bench``: each module has ``run(json_path, quick) -> dict``."""
