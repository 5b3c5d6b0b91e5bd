"""Synthetic data: the five benchmark shapes and gastruloid-like time-lapses.

Used by the sample data, the tests and the benchmarks.
"""
