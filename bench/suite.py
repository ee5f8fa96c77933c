"""`make test` as CI runs it: a fresh clone, its virtual environment, the whole suite; its time and its CPU.

Clones this repository's committed HEAD beside the checkout (``../.suite-bench-PID``, so ``../shared`` is found as
CI finds it beside its clone and the BROAD trials run), runs ``.ci/run`` there (``make test`` on the interpreter CI
picks) with ``--durations`` added, and prints one JSON object on its last line: for each run, the wall time of
``make test`` and of pytest in it, the CPU the whole run took (user and system, every process it started), the
interpreter, the counts and the slowest tests; and the goal (issue 32: under 5 minutes on two cores). make's own
lines go to stderr as they come (the suite takes about five minutes a run).

``--python P`` (again for more runs, each in a fresh clone) makes the venv with ``P`` instead: ``--python
/usr/bin/python3 --python python3`` compares the distribution's Python with this machine's default (a pyenv build
without profile-guided or link-time optimisation); ``ratio_to_first`` is each run's wall time over the first's.

A machine's speed can move from one minute to the next (on the two-core machine the suite is made on, three million
dict updates took anywhere from 0.66 s to 1.07 s within an hour), so a fixed loop is timed before and after each
run (``calibration_s``): compare runs at similar calibrations, and by their CPU as well as their wall time.

    .venv/bin/python -m bench.suite [--python P ...] [--keep] [--durations N]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
GOAL_S = 300.0
VENV_LINE = re.compile(r"^make: making the virtual environment \S+ with Python (\S+)")
SUMMARY = re.compile(r"^=+ (?P<counts>.*?) in (?P<s>[\d.]+)s")
COUNT = re.compile(r"(\d+) (passed|failed|skipped|errors?|xfailed|xpassed)")
DURATION = re.compile(r"^([\d.]+)s (setup|call|teardown)\s+(\S+)")


def calibration_s() -> float:
    """The best of three runs of a fixed pure-Python loop (dict and integer work, as the suite's is)."""
    best = float("inf")
    for _ in range(3):
        t = time.process_time()
        d: dict[int, int] = {}
        for i in range(1_000_000):
            d[i & 1023] = d.get(i & 1023, 0) + i
        best = min(best, time.process_time() - t)
    return round(best, 3)


def children_cpu() -> tuple[float, float]:
    import resource  # (POSIX: main() says so in one line elsewhere)

    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime, r.ru_stime


def run(keep: bool, durations: int, python: str | None) -> dict[str, object]:
    """One run of .ci/run in a fresh clone (``python``: the venv's interpreter, else the one CI picks)."""
    clone = ROOT.parent / f".suite-bench-{os.getpid()}"
    shutil.rmtree(clone, ignore_errors=True)
    got = subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], capture_output=True, text=True)
    if got.returncode != 0:
        raise SystemExit(f"bench.suite: could not clone into {clone}: {got.stderr.strip()[-300:]}")
    env = {**os.environ, "PYTEST_ADDOPTS": f"--durations={durations}"}
    env.pop("VIRTUAL_ENV", None)  # (make test makes and uses the clone's own)
    env.pop("PY", None)
    if python is not None:
        env["PY"] = python
    before = calibration_s()
    u0, s0 = children_cpu()
    start = time.monotonic()
    lines: list[str] = []
    base = None
    try:
        print(f"bench.suite: .ci/run in {clone}{f' with PY={python}' if python else ''} (about five minutes)",
              file=sys.stderr, flush=True)
        with subprocess.Popen(["bash", ".ci/run"], cwd=clone, env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True, errors="replace") as proc:
            assert proc.stdout is not None
            for line in proc.stdout:
                lines.append(line.rstrip("\n"))
                sys.stderr.write(line)
        code = proc.returncode
        wall = time.monotonic() - start
        u1, s1 = children_cpu()
        venv_python = clone / ".venv" / "bin" / "python"
        if venv_python.exists():
            base = subprocess.run([str(venv_python), "-c", "import sys; print(sys._base_executable)"],
                                  capture_output=True, text=True).stdout.strip() or None
    finally:
        if not keep:
            shutil.rmtree(clone, ignore_errors=True)
    after = calibration_s()
    counts: dict[str, int] = {}
    pytest_s = None
    version = None
    for line in lines:
        m = SUMMARY.match(line)
        if m:
            pytest_s = float(m["s"])
            counts = {kind.rstrip("s") if kind.startswith("error") else kind: int(n)
                      for n, kind in COUNT.findall(m["counts"])}
        v = VENV_LINE.match(line)
        if v:
            version = v[1]
    slowest = [{"s": float(m[1]), "phase": m[2], "test": m[3]} for line in lines if (m := DURATION.match(line))]
    return {
        "python": base, "python_version": version, "make_test_s": round(wall, 1), "pytest_s": pytest_s,
        "exit": code, "cpu_user_s": round(u1 - u0, 1), "cpu_sys_s": round(s1 - s0, 1),
        **{k: counts.get(k, 0) for k in ("passed", "failed", "skipped", "error")},
        "under_goal": code == 0 and wall < GOAL_S, "calibration_s": [before, after], "slowest": slowest,
        "kept": str(clone) if keep else None,
    }


def check_machine() -> None:
    if os.name != "posix":
        raise SystemExit("bench.suite: runs make test as CI does, on a POSIX system (Linux, macOS)")
    for tool in ("git", "make", "bash"):
        if shutil.which(tool) is None:
            raise SystemExit(f"bench.suite: needs {tool} on PATH")
    if not (ROOT / ".git").exists():
        raise SystemExit(f"bench.suite: {ROOT} is not a git checkout (it clones the committed HEAD)")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.suite", description=__doc__.split("\n\n")[0])
    ap.add_argument("--python", action="append", metavar="P",
                    help="make the venv with this interpreter (again for another run); default: the one CI picks")
    ap.add_argument("--keep", action="store_true", help="keep the clone (and its .venv) afterwards (the last run's)")
    ap.add_argument("--durations", type=int, default=15, help="how many of the slowest tests to list (default 15)")
    args = ap.parse_args(argv)
    if args.durations < 0:
        ap.error("--durations: must be 0 or more")
    for p in args.python or ():
        if shutil.which(p) is None:
            ap.error(f"--python {p}: no such interpreter on PATH or at that path")
    check_machine()
    pythons: list[str | None] = list(args.python or [None])
    runs = []
    try:
        for i, python in enumerate(pythons):
            runs.append(run(args.keep and i == len(pythons) - 1, args.durations, python))
    except KeyboardInterrupt:
        print("bench.suite: interrupted (the clone is removed unless --keep)", file=sys.stderr)
        return 130
    first = runs[0]["make_test_s"]
    for r in runs:
        r["ratio_to_first"] = round(float(r["make_test_s"]) / float(first), 3) if first else None  # type: ignore[arg-type]
    out = {"bench": "suite", "goal_s": GOAL_S, "cores": os.cpu_count(),
           "shared_beside": (ROOT.parent / "shared").is_dir(), "runs": runs}
    print(json.dumps(out))
    return 0 if all(r["exit"] == 0 for r in runs) else 1


if __name__ == "__main__":
    sys.exit(main())
