"""Benchmarks: each times or scores one part of the project against its alternatives and prints a table."""
