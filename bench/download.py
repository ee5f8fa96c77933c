"""The log download through damaged bytes: how often it ends byte-identical, and how long it takes.

The real board (fcb_sim's ``Board``) and the terminal's side (a ``LinkSession`` and the ``LogDownloader`` of
term/session/download.py, wired as the app wires them) joined by a byte proxy in each direction (``FaultyChannel``: each
byte has one bit flipped with the given probability), all on one simulated 1 ms clock: a download of a minute
costs seconds and every seed is exactly repeatable. The board records ``--record`` s of log in SAFE (about 120
chunks of 12 bytes for 1 s) over a clean link, then the damage is switched on and the download runs until it is
done or fails (its deadline: 20 s without anything new).

Per damage rate: downloads done and byte-identical, failed (cleanly, with a resume point), mean and worst time to
finish in simulated seconds, commands sent. One more row drops every LogStatus frame (the size and the CRC-32):
those must fail, with the reason. ``Rig`` is also the harness of tests/session/test_download.py.

``python -m bench.download [--seeds 20] [--record 1.0] [--rates 0,0.02,0.05,0.1]``; one JSON object on the last
line.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time

from term.core.protocol import LogStatus
from term.session.download import DONE, FAILED
from term.transports.loopback import Faults
from tests.support.download_rig import Rig, is_type


def sweep(rate: float, seeds: int, record_s: float, drop_status: bool = False) -> dict[str, object]:
    done = failed = wrong = 0
    times: list[float] = []
    requests: list[int] = []
    chunks = 0
    for seed in range(1, seeds + 1):
        rig = Rig(seed=seed, record_s=record_s)
        down = Faults(corrupt=rate, drop_frame=is_type(LogStatus) if drop_status else None)
        rig.faults(Faults(corrupt=rate), down)
        t0 = rig.now
        d = rig.download(limit_s=600.0)
        chunks = d.total_chunks or chunks
        requests.append(d.requests)
        if d.state == DONE:
            if d.data() == rig.truth():
                done += 1
                times.append(rig.now - t0)
            else:
                wrong += 1
        elif d.state == FAILED and d.reason:
            failed += 1
    return {
        "damage_pct": round(100 * rate, 1), "drop_logstatus": drop_status, "downloads": seeds, "chunks": chunks,
        "identical": done, "failed_cleanly": failed, "wrong": wrong,
        "time_mean_s": round(statistics.mean(times), 2) if times else None,
        "time_max_s": round(max(times), 2) if times else None,
        "requests_mean": round(statistics.mean(requests), 1),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.download", description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20, help="downloads per damage rate (default 20)")
    ap.add_argument("--record", type=float, default=1.0, help="seconds of log the board records (default 1)")
    ap.add_argument("--rates", default="0,0.02,0.05,0.1", help="damaged-byte probabilities, comma separated")
    a = ap.parse_args(argv)
    try:
        rates = [float(r) for r in a.rates.split(",")]
    except ValueError:
        print(f"bench.download: --rates wants numbers like 0,0.05, got {a.rates!r}", file=sys.stderr)
        return 2
    if a.seeds < 1 or not 0.05 <= a.record <= 30 or not all(0.0 <= r <= 0.5 for r in rates):
        print("bench.download: --seeds >= 1, --record in 0.05..30 s, --rates in 0..0.5", file=sys.stderr)
        return 2
    wall = time.perf_counter()
    rows = []
    for rate in rates:
        rows.append(sweep(rate, a.seeds, a.record))
        print(json.dumps(rows[-1]), flush=True)
    rows.append(sweep(0.0, min(a.seeds, 5), a.record, drop_status=True))
    print(json.dumps(rows[-1]), flush=True)
    print(json.dumps({"bench": "download", "seeds": a.seeds, "record_s": a.record, "rows": rows,
                      "wall_s": round(time.perf_counter() - wall, 1)}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
