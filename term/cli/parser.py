"""`term`'s command line as one argparse parser: flying is the default (no command), the other jobs are
subcommands. Shell completion (argcomplete) reads this same parser; nothing else builds one.

Global options (-v/--verbose, --version) are taken before and after the command alike. An option the main parser
and a command share (params' --serial, --sim, --config, ...) may stand on either side too: the command's copy
has no default of its own (argparse.SUPPRESS), so one given before the command is kept. A flying option given
before a command that does not take it is refused in one line (``check_command``), never silently dropped.
"""

from __future__ import annotations

import argparse
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any, NoReturn

from term.core.errors import UsageError
from term.core.protocol.numbers import cli_float, cli_int

LESSONS_DIR = Path(__file__).resolve().parents[1] / "lessons"  # the built-in lessons (term/lessons/spec.py)


def docs_dir() -> Path:
    """Where the docs/ the help texts name are: a clone's docs/, else the copy a wheel installs as term/_docs
    (pyproject.toml; fcb_sim/cbuild.py's docs_dir is the same for fcb-sim's help)."""
    term = Path(__file__).resolve().parents[1]
    clone = term.parent / "docs"
    return clone if (clone / "architecture.md").is_file() else term / "_docs"


def docs_line() -> str:
    return f"The docs/ files the help names are in {docs_dir()}."


# Any number a value may be (-1e308, -.5, -inf): a value, never an unknown option (argparse knows only -1 and -1.5)
_NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$|^-(inf|infinity|nan)$", re.IGNORECASE)


class _Parser(argparse.ArgumentParser):
    def __init__(self, *args: Any, **kw: Any) -> None:
        super().__init__(*args, **kw)
        self._negative_number_matcher = _NEGATIVE_NUMBER  # (no option of ours looks like a number)

    def error(self, message: str) -> NoReturn:  # one line, not usage + message
        raise UsageError(f"{message} (see {self.prog} --help)")


def version_text() -> str:
    """The installed package's version and the protocol version this terminal speaks."""
    from importlib.metadata import PackageNotFoundError, version

    from term.core.protocol import PROTOCOL_VERSION

    try:
        installed = version("quadrupel")
    except PackageNotFoundError:
        installed = "(not installed)"
    return f"{installed} (protocol v{PROTOCOL_VERSION})"


class _LazyVersion(argparse._VersionAction):
    """--version, its text made when it is given: the installed package's metadata costs every start-up some
    40 ms of CPU otherwise (a second of waiting on a busy machine)."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any,
                 option_string: str | None = None) -> None:
        if callable(self.version):
            self.version = self.version()
        super().__call__(parser, namespace, values, option_string)


def _add_global(p: argparse.ArgumentParser, version: Callable[[], str], command: bool) -> None:
    """-v and --version: on the main parser and on every command (there without a default: see the module doc)."""
    p.add_argument("-v", "--verbose", action="store_true", default=argparse.SUPPRESS if command else False,
                   help="log everything of term's to term.log in the platform's log directory (warnings always go "
                   "there)")
    p.add_argument("--version", action=_LazyVersion, version=version,  # type: ignore[arg-type]
                   help="print term's and the protocol's version")


def serial_ports() -> list[tuple[str, str]]:
    """The serial ports this machine shows (pyserial's list_ports), as (device, description)."""
    try:
        from serial.tools import list_ports

        return sorted((port.device, port.description) for port in list_ports.comports())
    except Exception:  # a platform pyserial cannot enumerate: no list, not an error
        return []


def builtin_lessons() -> dict[str, str]:
    """The built-in lessons' numbers and titles from their file names (01-arm.toml -> {"1": "arm"}): completion."""
    out = {}
    for path in sorted(LESSONS_DIR.glob("[0-9][0-9]-*.toml")):
        number, _, title = path.stem.partition("-")
        out[str(int(number))] = title.replace("-", " ")
    return out


def _link_options(p: argparse.ArgumentParser | Any, for_params: bool) -> None:
    """The options that name the board's link, shared by flying and params."""
    src = p.add_mutually_exclusive_group()
    serial_arg = src.add_argument("--serial", metavar="PATH",
                                  help="the board's serial port (or any pty), e.g. /dev/ttyUSB0 or COM3, or a board "
                                  "behind a serial-over-network server: socket://HOST:PORT, rfc2217://HOST:PORT")
    serial_arg.completer = lambda **_: [device for device, _ in serial_ports()]  # type: ignore[attr-defined]
    src.add_argument("--sim", action="store_true", help="start the simulated board (fcb-sim serve --pty)" + (
        " for this" if for_params else " and fly it; its BLE radio is connected too, for the handover (key 8)"))
    p.add_argument("--ble", metavar="ADDR", help="the board's BLE address (F0:5A:00:00:00:01; on macOS its UUID): "
                   "alone, over BLE; with --serial, the radio beside the cable for the handover (key 8)")
    p.add_argument("--baud", type=cli_int, default=None, help="serial speed (default 115200)")
    p.add_argument("--hci", metavar="TRANSPORT", default=None,
                   help="BLE through a bumble HCI transport instead of the system's radio, e.g. usb:0")
    p.add_argument("--ble-timeout", type=cli_float, default=10.0, metavar="S",
                   help="seconds to look for the BLE board (default 10)")
    p.add_argument("--seed", type=cli_int, default=1, help="--sim: noise seed (same seed, same flight)")
    p.add_argument("--sim-link", choices=("pty", "tcp"), default=None, help="--sim: the simulated board's cable, a "
                   "pseudo-terminal (pty, where there are: Linux, macOS) or a loopback TCP port (tcp: socket://, the "
                   "default where there are no pseudo-terminals, e.g. Windows)")
    from term.core.protocol import PRESETS

    p.add_argument("--preset", default=None, choices=sorted(PRESETS), help="--sim: the board's parameters, "
                   "'default' or 'report' (the lab report's board: Table 1, the complementary filter, the Figure 10 "
                   "height estimator)")
    p.add_argument("--config", type=Path, default=None,
                   help="config file (default: the platform's; 'term --config-path' shows where)")


def _flying_options(p: argparse.ArgumentParser) -> None:
    from term.core.protocol import SIM_SCENARIOS

    fly = p.add_argument_group("flying (no command)", "term --sim | --serial PATH [--ble ADDR] | --ble ADDR")
    _link_options(fly, for_params=False)
    fly.add_argument("--no-radio", action="store_true", help="--sim: the cable only, no simulated BLE radio")
    fly.add_argument("--board", choices=["python", "c"], default="python", help="--sim: the board in the "
                     "simulator, python (fcb_sim) or c (firmware/board/, built with cc; no radio); docs/firmware.md")
    fly.add_argument("--scenario", default=None, choices=SIM_SCENARIOS, help="--sim: initial conditions and "
                     "disturbances")
    fly.add_argument("--config-path", action="store_true", help="print where the config file is read from and exit")
    fly.add_argument("--link-timeout", type=cli_float, default=None, help="seconds without data before LINK LOST")
    fly.add_argument("--log-dir", type=Path, default=None, help="where downloaded logs are written as CSV")
    fly.add_argument("--no-joystick", action="store_true", help="keyboard only; do not look for a joystick")
    fly.add_argument("--no-bell", action="store_true", help="no terminal bell on LINK LOST, PANIC, low battery or "
                     "a crash (the config's [alarms] bell)")
    fly.add_argument("--no-record", action="store_true", help="do not record this session (by default every "
                     "frame both ways and every event is kept: 'term recordings')")
    fly.add_argument("--record-dir", type=Path, default=None, help="where session recordings are kept (default: "
                     "the platform's user data directory)")
    lesson = fly.add_argument("--lesson", type=cli_int, default=None, metavar="N", help="--sim: start lesson N "
                              f"(built in: {', '.join(f'{n} {t}' for n, t in builtin_lessons().items())}; a "
                              "teacher's with --lessons; docs/lessons.md)")
    lesson.completer = lambda **_: builtin_lessons()  # type: ignore[attr-defined]
    fly.add_argument("--demo", action="store_true", help="--sim: the autopilot flies a tour of the features, with "
                     "captions (any key of yours takes control)")
    fly.add_argument("--lessons", type=Path, default=None, metavar="DIR", help="--sim: a directory of lesson files "
                     "(*.toml) beside the built-in ones (a teacher's)")
    _add_foxglove(fly)
    _add_mavlink(fly)


# --- term --mavlink (term/data/mavlink.py; helper mavlink) ---
def _add_mavlink(p: argparse.ArgumentParser | Any) -> None:
    p.add_argument("--mavlink", metavar="[udp:|tcp:]HOST:PORT", nargs="?", const="udp:127.0.0.1:14550",
                   default=None, help="send the flight to a MAVLink ground station there and take its messages "
                   "(QGroundControl, MAVProxy; alone: udp:127.0.0.1:14550; needs the 'mavlink' extra); "
                   "docs/mavlink.md")
    p.add_argument("--mavlink-public", action="store_true", help="--mavlink may name a host that is not this "
                   "machine (the flight leaves it)")


def _add_foxglove(p: argparse.ArgumentParser | Any) -> None:
    p.add_argument("--foxglove", metavar="[HOST:]PORT", default=None, help="serve the session live to Foxglove "
                   "(ws://HOST:PORT, loopback unless a host is given; needs the 'foxglove' extra); docs/recording.md")
    p.add_argument("--foxglove-public", action="store_true", help="let --foxglove listen beyond this machine (a "
                   "host other than loopback, 0.0.0.0: every interface): the whole flight to the network")


def _plot(p: argparse.ArgumentParser) -> None:
    p.add_argument("log", nargs="?", type=Path, help="a session recording (.mcap) or a CSV of the log download (F5)")
    p.add_argument("--latest", action="store_true", help="the newest session recording (instead of a file)")
    p.add_argument("-o", "--output", type=Path, required=True, help="image to write (.png, .svg, .pdf)")
    p.add_argument("--signals", default=None, help="comma-separated series to draw, by field or export column "
                   "(phi,theta or phi_deg; default: every panel)")
    p.add_argument("--from", dest="start", type=cli_float, default=None, metavar="S",
                   help="start of the time window (s)")
    p.add_argument("--to", dest="end", type=cli_float, default=None, metavar="S", help="end of the time window (s)")
    p.add_argument("--dir", type=Path, default=None, help="where recordings are kept (default: 'term recordings')")


def _scan(p: argparse.ArgumentParser) -> None:
    p.add_argument("--hci", metavar="TRANSPORT", default=None, help="bumble HCI transport instead of the system's")
    p.add_argument("--timeout", type=cli_float, default=3.0, help="seconds to scan (default 3)")


def _export(p: argparse.ArgumentParser) -> None:
    p.add_argument("source", nargs="?", type=Path, help="a session recording (.mcap) or a flash-log CSV")
    p.add_argument("--latest", action="store_true", help="the newest session recording (instead of a file)")
    p.add_argument("-o", "--output", type=Path, required=True, help="file to write (.mcap or .csv)")
    p.add_argument("-f", "--format", choices=("mcap", "csv", "tlog"), default=None, help="default: from the output's "
                   "suffix (tlog: a MAVLink telemetry log, needs the 'mavlink' extra; docs/mavlink.md)")
    p.add_argument("--board-units", action="store_true", help="CSV in the board's units (raw field values)")
    p.add_argument("--raw", action="store_true", help="MCAP: the link's raw bytes and the station's records too "
                   "(channels in the quadrupel-frames encoding other readers skip; 'term replay' plays the file)")
    p.add_argument("--dir", type=Path, default=None, help="where recordings are kept (default: 'term recordings')")


def _recordings(p: argparse.ArgumentParser) -> None:
    p.add_argument("--dir", type=Path, default=None, help="where recordings are kept (default: the platform's "
                   "user data directory)")


def _replay(p: argparse.ArgumentParser) -> None:
    p.add_argument("source", nargs="?", type=Path, help="a session recording (.mcap, or a 'term export' MCAP)")
    p.add_argument("--latest", action="store_true", help="the newest session recording (instead of a file)")
    p.add_argument("--speed", type=cli_float, default=1.0, help="playback speed, 0.25 to 16 (default 1)")
    _add_foxglove(p)
    p.add_argument("--dir", type=Path, default=None, help="where recordings are kept (default: 'term recordings')")
    p.add_argument("--config", type=Path, default=None, help="config file (keys, plots; default: the platform's)")


def _params(p: argparse.ArgumentParser) -> None:
    _link_options(p, for_params=True)
    # no choices: run_command names the nearest action ("did you mean 'list'?"); completion offers them
    action = p.add_argument("action", nargs="?", help="list | get NAME | set NAME VALUE | save FILE | load FILE | "
                            "diff FILE")
    action.completer = _params_actions  # type: ignore[attr-defined]
    p.add_argument("words", nargs="*", help="the action's NAME, VALUE or FILE")


def _params_actions(**_: Any) -> tuple[str, ...]:
    from term.session.param_client import ACTIONS

    return ACTIONS


# name: (one line for term --help, the command's own description, its options, its epilog)
COMMANDS: dict[str, tuple[str, str, Callable[[argparse.ArgumentParser], None], str]] = {
    "plot": ("draw a recording or a downloaded flight log to an image (needs the plot extra)",
             "Draw a session recording or a downloaded flight log to an image, in SI units (°, °/s, g, m, V). "
             "Needs matplotlib: pip install 'quadrupel[plot]'.", _plot, ""),
    "scan": ("list the BLE boards nearby", "List BLE boards advertising the board's service.", _scan, ""),
    "export": ("a recording or flash log as MCAP (Foxglove) or CSV",
               "Convert a session recording, or a flash log downloaded as CSV, to MCAP (Foxglove, PlotJuggler) or "
               "to CSV with the unit in each column (phi_deg, height_m).", _export, ""),
    "recordings": ("list the session recordings: start, length, size",
                   "List the session recordings (one file per session, every frame both ways on every link and "
                   "every event), oldest first.", _recordings, ""),
    "replay": ("play a recording back in the same screens, no board needed",
               "Play a session recording back in the terminal's screens (all panels, plots and events), no board "
               "needed. Keys: space pause, left/right 5 s back/on, +/- faster/slower, home from the start; F1 help, "
               "ctrl+q quit.", _replay, ""),
    "params": ("the board's parameters: list, get, set, save, load, diff",
               "The board's parameters (docs/parameters.md) over the same links as term: list them (name, value, "
               "unit, default; * changed), get or set one, save them to a TOML file, load one (only what differs is "
               "set) or diff the board against one.", _params,
               "examples: term params --sim list; term params --serial /dev/ttyUSB0 set ctrl.p1 0.45; "
               "term params --sim --preset report save report.toml. DOCS"),
}


def build_parser() -> argparse.ArgumentParser:
    """term's parser: flying's options, the global ones and one subparser per command (``args.command``; None
    is flying)."""
    def version() -> str:
        return f"term {version_text()}"

    p = _Parser(
        prog="term",
        usage="term [-v] [--sim | --serial PATH | --ble ADDR] [flying options]\n       term COMMAND [options] "
        f"({', '.join(COMMANDS)})",
        description="Ground station for the Quadrupel quadcopter: fly the board (or its simulator) with keyboard "
        "and joystick; gauges, link health, events, plots and log download. With no command, term flies.",
        epilog="Keys: press F1 in the terminal. Config: 'term --config-path' shows where term.toml is read from. "
        "Every command takes -v and --version, before or after its name; 'term COMMAND --help' tells more. "
        + docs_line(),
    )
    _add_global(p, version, command=False)
    sub = p.add_subparsers(dest="command", metavar="COMMAND", title="commands (none: fly, with the options below)")
    for name, (line, description, add, epilog) in COMMANDS.items():
        epilog = epilog.replace("DOCS", docs_line())
        child = sub.add_parser(name, help=line, description=description, epilog=epilog or None,
                               prog=f"term {name}")
        add(child)
        _add_global(child, version, command=True)
    _flying_options(p)  # (after the commands: --help lists the commands first)
    _share_defaults(p)
    return p


def _subparsers(p: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def _share_defaults(p: argparse.ArgumentParser) -> None:
    """A command's copy of a main-parser option gets no default, so the one given before the command survives."""
    main = {a.dest: a for a in p._actions}
    for child in _subparsers(p).values():
        for action in child._actions:
            other = main.get(action.dest)
            if other is None or action.dest in ("help", "version", "verbose"):
                continue
            assert action.default == other.default, f"{action.dest}: the same default on both sides"
            action.default = argparse.SUPPRESS


def check_command(p: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Refuse a flying option given before a command that does not take it (``term --sim plot ...``)."""
    if args.command is None:
        return
    child = _subparsers(p)[args.command]
    taken = {a.dest for a in child._actions}
    for action in p._actions:
        if action.dest in taken or not action.option_strings or action.default is argparse.SUPPRESS:
            continue
        if getattr(args, action.dest, action.default) != action.default:
            raise UsageError(f"{action.option_strings[0]} is an option of flying, not of 'term {args.command}' "
                             f"(see term {args.command} --help)")


def complete(p: argparse.ArgumentParser) -> None:
    """Shell completion (argcomplete exits when the shell asked; without argcomplete, nothing)."""
    try:
        import argcomplete
    except ImportError:
        return
    argcomplete.autocomplete(p)
