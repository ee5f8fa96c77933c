# PYTHON_ARGCOMPLETE_OK (shell completion: eval "$(register-python-argcomplete fcb-sim)")
"""`fcb-sim`: the simulated flight-control board from the command line.

Argument parsing and wiring only; each subcommand's work lives in the module that owns it. Errors a user can
cause (a missing file, a bad option) end in one line on stderr and exit status 2, never a traceback.
``fcb-sim --version`` and ``python -m fcb_sim`` as for term; ``-v`` logs at INFO (bumble's too) to stderr, which
``term --sim`` keeps in its log directory. ``serve --pty`` needs pseudo-terminals (POSIX; elsewhere it is one line
naming ``--tcp``); ``serve --tcp`` runs everywhere. POSIX-only modules are imported only where they are used.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
from collections.abc import Callable, Sequence
from typing import Any, NoReturn

from fcb_sim.errors import EXIT_INTERRUPTED, EXIT_USAGE, UsageError
from fcb_sim.lab.profile import cmd_profile
from fcb_sim.lab.replay_imu import cmd_replay
from fcb_sim.lab.scenarios import cmd_run
from term.core.protocol import LINK_TIMEOUT_S
from term.core.protocol.numbers import cli_float, cli_int


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (its own are the usage block plus the message); subcommands inherit it."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="fcb-sim",
        description="The Quadrupel flight-control board as software: headless flights, IMU replay, "
        "profiling, and a board served over a pseudo-terminal or a TCP port (and a virtual BLE radio).",
        epilog=_docs_line(),
    )
    from term.core.protocol import PROTOCOL_VERSION

    def version() -> str:
        return f"fcb-sim {_version()} (protocol v{PROTOCOL_VERSION})"

    _add_global(parser, version, command=False)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_run(sub)
    _add_replay_imu(sub)
    _add_profile(sub)
    _add_serve(sub)
    for child in sub.choices.values():  # -v and --version after the command too, as term's
        _add_global(child, version, command=True)
    return parser


def _docs_line() -> str:
    from fcb_sim.cbuild import docs_dir

    return f"The docs/ files the help names are in {docs_dir()}."


class _LazyVersion(argparse._VersionAction):
    """--version, its text made when it is given: reading the package's metadata cost every start-up (term --sim's
    board too) some 40 ms of CPU."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any,
                 option_string: str | None = None) -> None:
        if callable(self.version):
            self.version = self.version()
        super().__call__(parser, namespace, values, option_string)


def _add_global(p: argparse.ArgumentParser, version: Callable[[], str], command: bool) -> None:
    """A command's -v has no default of its own (argparse.SUPPRESS): one given before the command is kept."""
    p.add_argument("--version", action=_LazyVersion, version=version,  # type: ignore[arg-type]
                   help="print the version and exit")
    p.add_argument("-v", "--verbose", action="store_true", default=argparse.SUPPRESS if command else False,
                   help="log INFO and up (bumble's too) to stderr")


# One helper a subcommand, in the order --help lists them (argparse names no public type for `sub`).


def _add_run(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """run: headless scenarios (owner: fcb_sim/lab/scenarios.py)."""
    run = sub.add_parser("run", help="fly a scripted scenario as fast as possible and print metrics")
    scenario = run.add_argument("--scenario", default="hover", help="scenario name (see --list)")
    scenario.completer = _run_scenarios  # type: ignore[attr-defined]
    run.add_argument("--duration", type=cli_float, default=10.0, help="simulated seconds (default 10)")
    run.add_argument("--seed", type=cli_int, default=1, help="noise seed: the same seed flies the same flight")
    run.add_argument("--json", action="store_true", help="print one JSON object as the last line")
    run.add_argument("--list", action="store_true", help="list the scenarios and exit")
    run.add_argument("--filter", default=None,
                     help="on-board attitude filter for the RAW-mode scenarios (default: the best one)")
    run.add_argument("--fixed-point", action="store_true", help="RAW-mode scenarios: the Q16.16 filter variant")
    run.add_argument("--board", choices=["core", "python", "c", "c-float"], default="core",
                     help="core: the flight core alone (default); python or c: the whole board over its UART, "
                     "scenarios hover and height-hold (fcb_sim/hosts/cboard.py)")
    run.set_defaults(handler=_cmd_run)


def _run_scenarios(**_: Any) -> tuple[str, ...]:
    """Shell completion of run's --scenario (argcomplete)."""
    from fcb_sim.lab.scenarios import SCENARIOS

    return tuple(SCENARIOS)


def _add_replay_imu(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """replay-imu: RAW-path filters over recorded data (owner: fcb_sim/lab/replay_imu.py)."""
    rep = sub.add_parser("replay-imu", help="run an attitude filter over recorded IMU data (CSV)")
    rep.add_argument("input", nargs="?", help="CSV or CSV.gz with columns t, gx gy gz (rad/s), ax ay az (m/s²), "
                     "or the board's flash log as term writes it (t_us, sp sq sr, sax say saz)")
    rep.add_argument("--filter", default=None, help="filter name (default: the best one); see --list-filters")
    rep.add_argument("--fixed-point", action="store_true", help="run the filter's fixed-point variant (as the board)")
    rep.add_argument("--out", help="output CSV: t, roll, pitch, yaw (rad), qw, qx, qy, qz")
    rep.add_argument("--list-filters", action="store_true", help="list the filters and exit")
    rep.set_defaults(handler=cmd_replay)


def _add_profile(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """profile: the board's task timing (owner: fcb_sim/lab/profile.py)."""
    prof = sub.add_parser("profile", help="profile the firmware loop with the Cortex-M0 cycle-cost model")
    prof.add_argument("--mode", choices=["raw", "dmp"], default="raw", help="sensor path (default raw)")
    prof.add_argument("--scheduler", choices=["round-robin", "priority"], default="round-robin")
    prof.add_argument("--seconds", type=cli_float, default=30.0, help="simulated seconds (default 30)")
    prof.add_argument("--seed", type=cli_int, default=1)
    prof.add_argument("--json", action="store_true", help="print one JSON object as the last line")
    prof.add_argument("--log-scheme", choices=["delta8", "rice"], default="delta8",
                      help="flash log codec while profiling (default delta8, the report's)")
    prof.set_defaults(handler=cmd_profile)


def _add_serve(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """serve: the board in real time behind a pseudo-terminal or a TCP port (owner: fcb_sim/hosts/serve.py)."""
    from term.core.protocol import PRESETS

    serve = sub.add_parser("serve", help="run the board in real time behind a pseudo-terminal or a TCP port",
                           epilog=_docs_line())
    serve.add_argument("--pty", action="store_true", help="expose the UART on a fresh pseudo-terminal (Linux, macOS)")
    serve.add_argument("--tcp", metavar="[HOST:]PORT", default=None,
                       help="expose the UART on a TCP port instead, for pyserial's socket:// (term --serial "
                       "socket://127.0.0.1:PORT); one client at a time; loopback unless --tcp-public; port 0: a "
                       "free one (the first line printed names it)")
    serve.add_argument("--tcp-public", action="store_true",
                       help="let --tcp listen beyond loopback (whoever connects flies the board: no login)")
    serve.add_argument("--seed", type=cli_int, default=1)
    serve.add_argument("--scenario", default="bench", help="initial conditions and disturbances")
    serve.add_argument("--link-timeout", type=cli_float, default=LINK_TIMEOUT_S,
                       help="seconds of link silence before the failsafe (link.timeout_ms)")
    serve.add_argument("--preset", default="default", choices=sorted(PRESETS),
                       help="the board's parameters: default (the team's best) or report (the lab report's board: "
                       "Table 1, the complementary filter, the Figure 10 height estimator); docs/parameters.md")
    serve.add_argument("--board", choices=["python", "c"], default="python",
                       help="the board in the loop: python (fcb_sim) or c (firmware/board/, built with cc on demand)")
    serve.add_argument("--ble-hci", default=None, metavar="TRANSPORT",
                       help="also expose the board's BLE radio, e.g. tcp-server:127.0.0.1:PORT")
    serve.add_argument("--instructor", default=None, metavar="TRANSPORT",
                       help="the truth and the lessons' situations for term --sim (fcb_sim/hosts/instructor.py), e.g. "
                       "tcp-server:127.0.0.1:0 (loopback only; the address printed carries the token)")
    serve.add_argument("--instructor-public", action="store_true",
                       help="let --instructor listen beyond loopback (warned about: it can cut cables and motors)")
    serve.set_defaults(handler=_cmd_serve)


def _cmd_run(args: argparse.Namespace) -> int:
    """run: the flight core's scenarios, or a whole board (python or c) over its UART (fcb_sim/hosts/cboard.py)."""
    if getattr(args, "board", "core") == "core" or args.list:
        return cmd_run(args)
    from fcb_sim.hosts.cboard import cmd_run_board

    return cmd_run_board(args)


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("quadrupel")
    except PackageNotFoundError:
        return "(not installed)"


def _cmd_serve(args: argparse.Namespace) -> int:
    """serve: --pty needs termios and tty (imported where the pty is made: fcb_sim/hosts/serve.py, open_pty, whose
    one line names --tcp where they are missing); --tcp needs neither."""
    from fcb_sim.hosts.serve import cmd_serve

    return cmd_serve(args)


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    if "_ARGCOMPLETE" in os.environ:
        try:
            import argcomplete

            argcomplete.autocomplete(parser)
        except ImportError:
            pass
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    try:
        return int(args.handler(args) or 0)
    except UsageError as exc:
        print(f"fcb-sim: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
