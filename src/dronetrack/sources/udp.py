"""The UDP side of a Livox host client: its sockets, bound on all interfaces as the
Livox SDKs bind them and polled so that a thread sees a stop request, and the local
address the host reaches a device from.

Sharing a port.  With SO_REUSEADDR, Linux lets several UDP sockets bind one port,
hands every broadcast to each of them and every unicast datagram to the one bound
last only.  A second client on the host's command or point port would take the ACKs
and points of the first, which then stops with "no point packet"; those ports are
bound without it, so the second client's bind fails (``PORT_IN_USE``) and the first
runs on untouched.  Only a discovery port is shared: the device broadcasts to it
(SDK 1), and Livox-SDK2 binds its detection port 56000 with port reuse, as the
emulated Mid-360 on this machine does.
"""

from __future__ import annotations

import errno
import socket

from dronetrack.errors import DeviceError

__all__ = [
    "MAX_DATAGRAM",
    "POLL_S",
    "PORT_IN_USE",
    "is_local_address",
    "port_in_use",
    "route_source_ip",
    "udp_socket",
]

POLL_S = 0.05  # longest a thread blocks before it looks at the stop request
MAX_DATAGRAM = 2048  # the largest Livox datagram is 1400 bytes
# why a host port is taken, in the error that names it
PORT_IN_USE = "is in use on this host, most likely by another dronetrack live or info on this LiDAR"


def port_in_use(exc: OSError) -> bool:
    """Whether a bind failed because another socket holds the port."""
    return exc.errno == errno.EADDRINUSE


def udp_socket(
    port: int, what: str, rcvbuf: int = 0, *, shared: bool = False, key: str = ""
) -> socket.socket:
    """A UDP socket bound to ``port`` on all interfaces (as the SDKs bind), polling;
    ``shared``: with SO_REUSEADDR (a discovery port, see the module docstring).
    DeviceError if it cannot be bound; a port another socket holds is named as in use,
    with ``key``, the URI key that moves it."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        if shared:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        if rcvbuf:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        sock.bind(("0.0.0.0", port))
    except OSError as exc:
        sock.close()
        if port_in_use(exc):
            moved = f"; a second LiDAR needs its own (the URI's {key}=)" if key else ""
            raise DeviceError(f"UDP port {port} ({what}) {PORT_IN_USE}{moved}") from exc
        raise DeviceError(f"cannot bind UDP port {port} ({what}): {exc}") from exc
    sock.settimeout(POLL_S)
    return sock


def is_local_address(ip: str) -> bool:
    """Whether ``ip`` is one of this host's addresses (a socket can be bound to it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        try:
            probe.bind((ip, 0))
        except OSError:
            return False
        return True


def route_source_ip(device_ip: str, device_port: int) -> str:
    """The local address the host sends to ``device_ip`` from (a connected UDP socket
    sends nothing; the kernel only picks the route)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        try:
            probe.connect((device_ip, device_port))
        except OSError as exc:
            raise DeviceError(
                f"Livox device at {device_ip}: no route from this host: {exc}"
            ) from exc
        return str(probe.getsockname()[0])
