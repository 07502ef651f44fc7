"""The simulated autopilot's UDP links: one socket each, with its MAVLink parser, sender and peers.

Like PX4 SITL the main link *sends* from one socket (bound to any free port) to the UDP address where
MAVSDK listens and answers from that same socket; the pilot/GCS link is bound on 127.0.0.1 and answers
whoever spoke to it. Both speak MAVLink 2 as sysid 1, compid 1, each with its own sequence numbers.
Sockets are non-blocking: the endpoint waits on them with ``select`` and drains what arrived.
"""

from __future__ import annotations

import logging
import socket
from collections.abc import Iterator

from pymavlink.dialects.v20 import common as mavlink

from sim.autopilot_telemetry import Message

log = logging.getLogger("sim.autopilot")  # the endpoint's logger, as the program names it
Address = tuple[str, int]


class Link:
    """One UDP socket, its MAVLink parser and sender (own sequence numbers), and its peers."""

    def __init__(self, sock: socket.socket, peers: list[Address]) -> None:
        self.sock = sock
        self.peers = list(peers)
        self.tx = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        self.rx = mavlink.MAVLink(None)
        self.rx.robust_parsing = True

    @property
    def local_address(self) -> Address:
        """The (host, port) the socket is bound to."""
        host, port = self.sock.getsockname()[:2]
        return (host, port)

    def note_peer(self, addr: Address) -> bool:
        """Remember who spoke to us; True if it is new."""
        if addr in self.peers:
            return False
        self.peers.append(addr)
        return True

    def send(self, msg: Message, addr: Address | None = None) -> None:
        data = msg.pack(self.tx)
        for peer in [addr] if addr is not None else self.peers:
            try:
                self.sock.sendto(data, peer)
            except OSError as e:  # nobody listening yet, or the network went away
                log.debug("send to %s failed: %s", peer, e)

    def datagrams(self) -> Iterator[tuple[Address, bytes]]:
        """Each datagram waiting on the socket, with its sender, until none is left (never blocks)."""
        while True:
            try:
                data, addr = self.sock.recvfrom(65535)
            except (BlockingIOError, InterruptedError):
                return
            except OSError as e:  # e.g. ECONNREFUSED surfacing from an earlier send
                log.debug("recv failed: %s", e)
                return
            yield (addr[0], addr[1]), data

    def parse(self, data: bytes) -> list[Message]:
        """The MAVLink messages in one datagram (garbage is skipped)."""
        return self.rx.parse_buffer(data) or []

    def close(self) -> None:
        self.sock.close()


def open_links(target: Address, pilot_port: int | None) -> tuple[Link, Link | None]:
    """The main link sending to ``target``, and the pilot link on 127.0.0.1:``pilot_port`` (0 = a free port).

    ``pilot_port`` None opens no pilot link. Raises ``OSError`` (with both sockets closed) when the pilot
    port cannot be bound.
    """
    main = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    main.bind(("0.0.0.0", 0))
    main.setblocking(False)
    if pilot_port is None:
        return Link(main, [target]), None
    pilot = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        pilot.bind(("127.0.0.1", pilot_port))
    except OSError:
        main.close()
        pilot.close()
        raise
    pilot.setblocking(False)
    return Link(main, [target]), Link(pilot, [])
