"""The plain peer of ``pendsweep site``: a naive Python spring site, written as a lab would in an afternoon.

It speaks the same protocol to OpenSees (set-up, then frames; replies to the
get actions) with blocking reads, immediate ACKs (without them every step waits
about 40 ms for a delayed ACK) and a spring force ``k d``; no rig, no log, no
checks. ``python naive_site.py [k]`` prints its port, serves one client, exits.
"""

import socket
import struct
import sys

import numpy as np


def main() -> None:
    k = float(sys.argv[1]) if len(sys.argv) > 1 else 0.0
    server = socket.create_server(("127.0.0.1", 0))
    print(server.getsockname()[1], flush=True)
    conn, _ = server.accept()

    def receive(n: int) -> bytes:
        data = b""
        while len(data) < n:
            chunk = conn.recv(n - len(data))
            if not chunk:
                raise SystemExit(0)
            data += chunk
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_QUICKACK, 1)
        return data

    size = struct.unpack("<11i", receive(44))[10]
    d = 0.0
    while True:
        frame = np.frombuffer(receive(8 * size), "<f8")
        action = int(frame[0])
        if action == 99:
            return
        if action == 3:
            d = frame[1]
        elif action in (6, 7, 8, 9, 10, 11, 12, 13, 14, 15):
            reply = np.zeros(size)
            reply[0] = k * d if action == 10 else (k if action in (12, 13) else 0.0)
            conn.sendall(reply.tobytes())


if __name__ == "__main__":
    main()
