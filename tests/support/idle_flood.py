"""A flood of idle TCP connections, in a process of its own (so the process under test holds none of them):

    python -m tests.support.idle_flood HOST PORT N

opens N connections that send nothing, prints ``open N`` once it has asked for them all, then keeps N open (those
the server closed or answered are opened again every 0.2 s) until its stdin closes; then it prints ``reopened M``
and exits.
"""

from __future__ import annotations

import resource
import socket
import sys
import threading


def main(argv: list[str]) -> int:
    host, port, n = argv[0], int(argv[1]), int(argv[2])
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    want = n + 64
    if soft != resource.RLIM_INFINITY and soft < want:
        resource.setrlimit(resource.RLIMIT_NOFILE, (want if hard == resource.RLIM_INFINITY else min(want, hard), hard))
    stop = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), stop.set()), daemon=True).start()
    socks: list[socket.socket] = []
    reopened = 0

    def fill() -> int:
        opened = 0
        while len(socks) < n:
            sk = socket.socket()
            sk.setblocking(False)
            sk.connect_ex((host, port))
            socks.append(sk)
            opened += 1
        return opened

    fill()
    print(f"open {len(socks)}", flush=True)
    while not stop.wait(0.2):
        alive = []
        for sk in socks:
            try:
                sk.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT)
                gone = True  # closed, or answered (a refusal): a server says nothing to an idle client otherwise
            except BlockingIOError:
                gone = False
            except OSError as exc:
                gone = exc.errno != 107 and not isinstance(exc, InterruptedError)  # (107: not yet connected)
            if gone:
                sk.close()
            else:
                alive.append(sk)
        socks[:] = alive
        reopened += fill()
    print(f"reopened {reopened}", flush=True)
    for sk in socks:
        sk.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
