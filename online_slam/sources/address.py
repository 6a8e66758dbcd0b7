"""Live sources and sinks by address: ``-`` (standard input or output) and ``tcp://HOST:PORT``; no I/O here.

A live source is read as it arrives: its lines may come late (a latency budget by default) and a bad line is
skipped by default, where a file's stops the run.
"""

from __future__ import annotations

from urllib.parse import urlsplit

TCP = "tcp://"
"""The scheme of a TCP address."""


def is_tcp(spec: object) -> bool:
    """Whether a source or sink is a TCP address (``tcp://HOST:PORT``)."""
    return isinstance(spec, str) and spec.startswith(TCP)


def is_live(spec: object) -> bool:
    """Whether a source is read live: standard input (``-``) or a TCP address."""
    return str(spec) == "-" or is_tcp(spec)


def on_error_of(given: str | None, source: object) -> str:
    """The ``--on-error`` policy asked for, or the default for this source (skip for a live one, stdin or TCP: a
    live stream goes on; else stop)."""
    return given or ("skip" if is_live(source) else "stop")


def tcp_address(spec: str) -> tuple[str, int]:
    """``(host, port)`` of ``tcp://HOST:PORT`` (an IPv6 host in brackets: ``tcp://[::1]:5000``; port 0: any free one).

    Raises:
        ValueError: Not such an address; the message says what is expected.
    """
    expected = f"expected tcp://HOST:PORT (e.g. tcp://127.0.0.1:5000; port 0: any free port), got {spec!r}"
    parts = urlsplit(spec)
    try:
        port = parts.port
    except ValueError:
        raise ValueError(expected) from None
    if parts.scheme != "tcp" or not parts.hostname or port is None or parts.path not in ("", "/") or parts.query:
        raise ValueError(expected)
    return parts.hostname, port


def tcp_name(host: str, port: int) -> str:
    """The address ``tcp://HOST:PORT`` (an IPv6 host in brackets)."""
    return f"{TCP}[{host}]:{port}" if ":" in host else f"{TCP}{host}:{port}"
