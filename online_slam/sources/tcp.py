"""Live input over TCP: ``tcp://HOST:PORT`` listens and reads stream-v1 lines from one client at a time.

The lines of every connection make one stream, validated as one (line numbers run on over connections). A client
that disconnects does not end it: the next connection continues where the last one stopped, and meanwhile further
clients wait in the listen queue. The stream ends at an ``end`` line, or when ``stop`` says so (a signal: it is
asked at least every :data:`POLL_S` seconds while no line comes). A line a client left unfinished when it went away
is a bad line (skipped, under the live default ``--on-error skip``).
"""

from __future__ import annotations

import socket
import sys
from collections.abc import Callable, Iterator

from online_slam.errors import InputError
from online_slam.sources.address import tcp_address, tcp_name
from online_slam.sources.events import Event
from online_slam.sources.stream import parse_lines

POLL_S = 0.1
"""Seconds between two looks at ``stop`` while waiting for a client or a line."""
CHUNK = 1 << 16
"""Bytes read at once."""


def tell_stderr(message: str) -> None:
    """Say what a live source does (listening, a client came or went) on stderr."""
    print(f"online-slam: {message}", file=sys.stderr, flush=True)


def open_tcp(
    spec: str,
    on_error: Callable[[InputError], None] | None = None,
    max_latency: float = 0.0,
    stop: Callable[[], bool] | None = None,
    tell: Callable[[str], None] = tell_stderr,
) -> tuple[str, Iterator[Event]]:
    """Listen at ``spec`` at once (``tell`` names the address bound: with port 0, the port chosen), and read lazily.

    Args:
        spec: ``tcp://HOST:PORT``; HOST is the interface to listen on (``127.0.0.1``: this machine only,
            ``0.0.0.0``: every interface).
        on_error: None: the first bad line raises; else each is given to it and skipped.
        max_latency: Seconds a line may lie before the newest (a later stage reorders).
        stop: Asked while waiting; True ends the stream there.
        tell: Told what the source does: listening, a client connected or gone.

    Returns:
        (the bound address ``tcp://HOST:PORT``, the events up to an ``end`` line or a stop).

    Raises:
        InputError: Not a TCP address, or the address cannot be listened on (in use, not this machine's).
    """
    try:
        host, port = tcp_address(spec)
        listener = socket.create_server((host, port), family=_family(host), backlog=4)
    except (ValueError, OSError) as exc:
        raise InputError(spec, 0, "", f"cannot listen: {getattr(exc, 'strerror', None) or exc}") from None
    listener.settimeout(POLL_S)
    name = tcp_name(host, listener.getsockname()[1])
    tell(f"listening on {name}")
    lines = _lines(listener, name, stop or (lambda: False), tell)
    return name, parse_lines(name, lines, on_error, max_latency)


def _family(host: str) -> socket.AddressFamily:
    return socket.AF_INET6 if ":" in host else socket.AF_INET


def _lines(
    listener: socket.socket, name: str, stop: Callable[[], bool], tell: Callable[[str], None]
) -> Iterator[str | InputError]:
    """The lines of one client after another (an unfinished last line: an :class:`InputError`), until ``stop``."""
    with listener:
        while not stop():
            try:
                client, peer = listener.accept()
            except TimeoutError:
                continue
            tell(f"client {peer[0]}:{peer[1]} connected to {name}")
            with client:
                client.settimeout(POLL_S)
                yield from _client_lines(client, name, stop)
            if not stop():
                tell(f"client {peer[0]}:{peer[1]} disconnected; waiting for the next on {name}")


def _client_lines(client: socket.socket, name: str, stop: Callable[[], bool]) -> Iterator[str | InputError]:
    """One client's lines, until it disconnects or ``stop``."""
    rest = b""
    while not stop():
        try:
            chunk = client.recv(CHUNK)
        except TimeoutError:
            continue
        except OSError:  # reset by the peer: as a disconnection
            chunk = b""
        if not chunk:
            if rest.strip():
                yield InputError(name, 0, "", "cut line: the client disconnected part-way through it")
            return
        *lines, rest = (rest + chunk).split(b"\n")
        for line in lines:
            try:
                yield line.decode("utf-8")
            except UnicodeDecodeError as exc:
                yield InputError(name, 0, "", f"not UTF-8 text ({exc.reason})")
