"""Reproducible benchmarks: each prints its figures as ratios against a peer in the same run."""
