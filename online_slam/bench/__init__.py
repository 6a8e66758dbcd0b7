"""Benchmarks (figures and ratios against peers measured in the same run) and the peer adapters they use.

Peers (GTSAM) are optional: install the ``peers`` extra. Nothing outside this package imports them.
"""
