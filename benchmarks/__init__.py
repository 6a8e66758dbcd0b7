"""Benchmarks of online-slam beside peers measured in the same run, and the peer adapters they and the tests use.

Kept beside the installed package, not in it: run ``python -m benchmarks`` from the repository root. Peers (GTSAM)
are optional: install the ``peers`` extra. The package ``online_slam`` never imports this one.
"""
