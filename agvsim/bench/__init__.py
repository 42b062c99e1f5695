"""Benchmarks behind ``agvsim bench`` (one module per benchmark)."""
