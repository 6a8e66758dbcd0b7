"""Command line: a parser and a ``run()`` per command; the only place that touches argv."""
