"""Benchmarks run as `softproxy bench NAME`: each prints a table and writes JSON and a chart."""
