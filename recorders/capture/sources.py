"""The source kinds a manifest's `source = "..."` may name: a plain table from URL scheme to class."""

from __future__ import annotations

from .base import Source, SourceError
from .serial_port import SerialSource
from .tail import TailSource
from .tcp import TcpSource
from .tcp_listen import TcpListenSource
from .udp import UdpSource

SOURCE_KINDS: dict[str, type[Source]] = {
    "serial": SerialSource,
    "udp": UdpSource,
    "tcp": TcpSource,
    "tcp-listen": TcpListenSource,
    "tail": TailSource,
}


def make_source(url: str) -> Source:
    """The Source for an address such as udp://127.0.0.1:5000; SourceError names what is wrong."""
    scheme = url.partition(":")[0]
    kind = SOURCE_KINDS.get(scheme)
    if kind is None:
        raise SourceError(f"{url}: unknown source kind {scheme!r}; use one of "
                          + ", ".join(f"{k}:" for k in SOURCE_KINDS))
    return kind(url)
