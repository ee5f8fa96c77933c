# PYTHON_ARGCOMPLETE_OK (shell completion: eval "$(register-python-argcomplete term)")
"""`term`: the pilot's terminal from the command line. Parsing and wiring only; the one place that knows every part.

    term --serial /dev/ttyUSB0 [--baud 115200]    fly the real board (or any pty)
    term --sim [--seed N] [--scenario NAME]       start `fcb-sim serve --pty --ble-hci ...` and fly it over that
                                                  real pty, its radio connected too (key 8 hands over to BLE)
    term --ble ADDR [--hci TRANSPORT]             fly over BLE only (opens on the wireless screen)
    term --serial PATH --ble ADDR [--hci T]       the cable and the radio, for the handover (as --sim)
    term scan [--hci TRANSPORT]                   list BLE boards nearby
    term params [--serial P|--ble A|--sim] list   the board's parameters; get, set, save, load, diff a file
    term plot SESSION|LOG.csv|--latest -o out.png a recording or downloaded flight log, in SI units
    term export SESSION|LOG.csv|--latest -o OUT   a session recording or flash log as MCAP or CSV (its units)
    term recordings                               list the session recordings: start, length, size
    term replay SESSION|--latest                  play a recording back in the same screens, no board needed
    term                                          no board given: one line naming the serial ports seen
    term --version, python -m term                the version (and the protocol's); the same program

term's own log (warnings always, everything with --verbose) and the simulated board's stderr are kept in the
platform's log directory (term/session/applog.py): the TUI owns the terminal, so nothing can be printed while it runs.
POSIX-only parts (SIGHUP, the hung-up-tty watcher, the child's PR_SET_PDEATHSIG) are skipped where missing.

Errors a user can cause end in one line on stderr and a non-zero exit, never a traceback: 2 for bad arguments,
a missing port or a board that will not start; 3 for a board that speaks another protocol version.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import os
import select
import signal
import sys
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any, NoReturn

from term.core.errors import EXIT_INTERRUPTED, EXIT_USAGE, EXIT_VERSION, UsageError
from term.core.protocol.numbers import cli_float, cli_int
from term.core.schema import Number
from term.session.sim import SimBoard

if TYPE_CHECKING:
    from term.session.config import Config

__all__ = ["EXIT_USAGE", "EXIT_VERSION", "UsageError", "main"]

BLE_TIMEOUT = Number(0.1, 600.0, unit="s")  # --ble-timeout, scan --timeout: seconds to look for the board


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line, not usage + message
        raise UsageError(f"{message} (see {self.prog} --help)")


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(
        prog="term",
        description="Ground station for the Quadrupel quadcopter: fly the board (or its simulator) with keyboard "
        "and joystick; gauges, link health, events, plots and log download.",
        epilog="more: 'term plot LOG.csv -o out.png' draws a downloaded log; 'term scan' lists BLE boards. "
        "Keys: press F1 in the terminal. Config: 'term --config-path' shows where term.toml is read from.",
    )
    src = p.add_mutually_exclusive_group()
    serial_arg = src.add_argument("--serial", metavar="PATH",
                                  help="the board's serial port (or any pty), e.g. /dev/ttyUSB0 or COM3")
    serial_arg.completer = lambda **_: [device for device, _ in serial_ports()]  # type: ignore[attr-defined]
    src.add_argument("--sim", action="store_true", help="start the simulated board (fcb-sim serve --pty) and fly "
                     "it; its BLE radio is connected too, for the handover (key 8)")
    p.add_argument("--ble", metavar="ADDR", help="the board's BLE address: alone, fly over BLE; with --serial, "
                   "the radio beside the cable for the handover (key 8)")
    p.add_argument("--baud", type=cli_int, default=None, help="serial speed (default 115200)")
    p.add_argument("--hci", metavar="TRANSPORT", default=None,
                   help="BLE through a bumble HCI transport instead of the system's radio, e.g. usb:0")
    p.add_argument("--ble-timeout", type=cli_float, default=10.0, metavar="S",
                   help="seconds to look for the BLE board (default 10)")
    p.add_argument("--no-radio", action="store_true", help="--sim: the cable only, no simulated BLE radio")
    p.add_argument("--board", choices=["python", "c"], default="python", help="--sim: the board in the "
                   "simulator, python (fcb_sim) or c (firmware/board/, built with cc; no radio); docs/firmware.md")
    p.add_argument("--seed", type=cli_int, default=1, help="--sim: noise seed (same seed, same flight)")
    p.add_argument("--scenario", default=None, help="--sim: initial conditions and disturbances")
    p.add_argument("--preset", default=None, help="--sim: the board's parameters, 'default' or 'report' (the lab "
                   "report's board: Table 1, the complementary filter, the Figure 10 height estimator)")
    p.add_argument("--config", type=Path, default=None, help="config file (default: the platform's, see below)")
    p.add_argument("--config-path", action="store_true", help="print where the config file is read from and exit")
    p.add_argument("--link-timeout", type=cli_float, default=None, help="seconds without data before LINK LOST")
    p.add_argument("--log-dir", type=Path, default=None, help="where downloaded logs are written as CSV")
    p.add_argument("--no-joystick", action="store_true", help="keyboard only; do not look for a joystick")
    p.add_argument("--no-bell", action="store_true", help="no terminal bell on LINK LOST, PANIC, low battery or a "
                   "crash (the config's [alarms] bell)")
    p.add_argument("--no-record", action="store_true", help="do not record this session (by default every frame "
                   "both ways and every event is kept: 'term recordings')")
    p.add_argument("--record-dir", type=Path, default=None, help="where session recordings are kept (default: "
                   "the platform's user data directory)")
    p.add_argument("--lesson", type=cli_int, default=None, metavar="N", help="--sim: start lesson N (Ctrl+P lists "
                   "them: 'lesson'); docs/lessons.md")
    p.add_argument("--demo", action="store_true", help="--sim: the autopilot flies a tour of the features, with "
                   "captions (any key of yours takes control)")
    p.add_argument("--lessons", type=Path, default=None, metavar="DIR", help="--sim: a directory of lesson files "
                   "(*.toml) beside the built-in ones (a teacher's)")
    _add_foxglove(p)
    _add_common(p)
    return p


def _add_common(p: argparse.ArgumentParser) -> None:
    p.add_argument("-v", "--verbose", action="store_true",
                   help="log everything of term's to term.log in the platform's log directory (warnings always go "
                   "there)")
    p.add_argument("--version", action="version", version=f"%(prog)s {version_text()}")


def version_text() -> str:
    """The installed package's version and the protocol version this terminal speaks."""
    from importlib.metadata import PackageNotFoundError, version

    from term.core.protocol import PROTOCOL_VERSION

    try:
        installed = version("quadrupel")
    except PackageNotFoundError:
        installed = "(not installed)"
    return f"{installed} (protocol v{PROTOCOL_VERSION})"


def serial_ports() -> list[tuple[str, str]]:
    """The serial ports this machine shows (pyserial's list_ports), as (device, description)."""
    try:
        from serial.tools import list_ports

        return sorted((port.device, port.description) for port in list_ports.comports())
    except Exception:  # a platform pyserial cannot enumerate: no list, not an error
        return []


def _ports_hint() -> str:
    ports = serial_ports()
    if not ports:
        return "no serial ports seen here"
    return "serial ports seen here: " + ", ".join(
        device if desc in ("", "n/a", device) else f"{device} ({desc})" for device, desc in ports
    )


def _complete() -> None:
    """Shell completion (argcomplete; it exits when the shell asked): term's options and subcommands in one parser."""
    try:
        import argcomplete
    except ImportError:
        return
    parser = build_parser()
    sub = parser.add_subparsers(dest="command", required=False)
    for name, build in (("plot", build_plot_parser), ("scan", build_scan_parser), ("export", build_export_parser),
                        ("recordings", build_recordings_parser), ("replay", build_replay_parser),
                        ("params", build_params_parser)):
        child = build()
        sub.add_parser(name, parents=[child], add_help=False, help=child.description)
    argcomplete.autocomplete(parser)


def _start_log(verbose: bool) -> None:
    from term.session.applog import setup_logging

    path = setup_logging(verbose)
    if verbose and path is not None:
        print(f"term: logging to {path}", file=sys.stderr)


def build_plot_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="term plot", description="Draw a session recording or a downloaded flight log to an image, "
                "in SI units (°, °/s, g, m, V).")
    p.add_argument("log", nargs="?", type=Path, help="a session recording (.mcap) or a CSV of the log download (F5)")
    p.add_argument("--latest", action="store_true", help="the newest session recording (instead of a file)")
    p.add_argument("-o", "--output", type=Path, required=True, help="image to write (.png, .svg, .pdf)")
    p.add_argument("--signals", default=None, help="comma-separated series to draw, by field or export column "
                   "(phi,theta or phi_deg; default: every panel)")
    p.add_argument("--from", dest="start", type=cli_float, default=None, metavar="S",
                   help="start of the time window (s)")
    p.add_argument("--to", dest="end", type=cli_float, default=None, metavar="S", help="end of the time window (s)")
    p.add_argument("--dir", type=Path, default=None, help="where recordings are kept (default: 'term recordings')")
    return p


def build_scan_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="term scan", description="List BLE boards advertising the board's service.")
    p.add_argument("--hci", metavar="TRANSPORT", default=None, help="bumble HCI transport instead of the system's")
    p.add_argument("--timeout", type=cli_float, default=3.0, help="seconds to scan (default 3)")
    _add_common(p)
    return p


def build_export_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="term export", description="Convert a session recording, or a flash log downloaded as CSV, "
                "to MCAP (Foxglove, PlotJuggler) or to CSV with the unit in each column (phi_deg, height_m).")
    p.add_argument("source", nargs="?", type=Path, help="a session recording (.mcap) or a flash-log CSV")
    p.add_argument("--latest", action="store_true", help="the newest session recording (instead of a file)")
    p.add_argument("-o", "--output", type=Path, required=True, help="file to write (.mcap or .csv)")
    p.add_argument("-f", "--format", choices=("mcap", "csv"), default=None, help="default: from the output's suffix")
    p.add_argument("--board-units", action="store_true", help="CSV in the board's units (raw field values)")
    p.add_argument("--raw", action="store_true", help="MCAP: the link's raw bytes and the station's records too "
                   "(channels in the quadrupel-frames encoding other readers skip; 'term replay' plays the file)")
    p.add_argument("--dir", type=Path, default=None, help="where recordings are kept (default: 'term recordings')")
    return p


def build_recordings_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="term recordings", description="List the session recordings (one file per session, every "
                "frame both ways on every link and every event), oldest first.")
    p.add_argument("--dir", type=Path, default=None, help="where recordings are kept (default: the platform's "
                   "user data directory)")
    return p


def _export(a: argparse.Namespace) -> int:
    from term.data.export import ExportError, export
    from term.data.recording import RecordingError, latest

    if a.latest == (a.source is not None):
        raise UsageError("give one recording or flash log, or --latest")
    try:
        src = latest(a.dir) if a.latest else a.source
        res = export(src, a.output, a.format, a.board_units, raw=a.raw, progress=_progress_bar("exporting"))
    except (ExportError, RecordingError) as exc:
        raise UsageError(str(exc)) from None
    what = "frames and events" if res.kind == "session" else "records"
    cut = "" if res.complete else " (the recording was cut short: all of it that was on disk)"
    print(f"wrote {a.output}: {res.rows} {what} from {src}{cut}")
    return 0


def _progress_bar(what: str) -> Any:
    """A progress callback drawing one line on stderr (only on a terminal: a pipe gets none)."""
    if not sys.stderr.isatty():
        return None

    def show(done: int, total: int | None) -> None:
        if total:
            frac = min(1.0, done / total)
            bar = "█" * round(frac * 30)
            text = f"\r{what} {bar:<30} {frac:4.0%} {done:,} of {total:,}"
        else:
            text = f"\r{what} {done:,} messages"
        end = "\n" if total is not None and done >= total else ""
        print(text, end=end, file=sys.stderr, flush=True)

    return show


def build_replay_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="term replay", description="Play a session recording back in the terminal's screens (all "
                "panels, plots and events), no board needed. Keys: space pause, left/right 5 s back/on, +/- "
                "faster/slower, home from the start; F1 help, ctrl+q quit.")
    p.add_argument("source", nargs="?", type=Path, help="a session recording (.mcap, or a 'term export' MCAP)")
    p.add_argument("--latest", action="store_true", help="the newest session recording (instead of a file)")
    p.add_argument("--speed", type=cli_float, default=1.0, help="playback speed, 0.25 to 16 (default 1)")
    _add_foxglove(p)
    p.add_argument("--dir", type=Path, default=None, help="where recordings are kept (default: 'term recordings')")
    return p


def _replay(a: argparse.Namespace) -> int:
    from term.data.recording import RecordingError, latest
    from term.data.replay import SPEEDS, Replay
    from term.session.config import ConfigError, load_config

    if a.latest == (a.source is not None):
        raise UsageError("give one recording, or --latest")
    if not SPEEDS[0] <= a.speed <= SPEEDS[-1]:  # (nan fails both)
        raise UsageError(f"--speed must be between {SPEEDS[0]:g} and {SPEEDS[-1]:g}, got {a.speed:g}")
    try:
        replay = Replay.load(latest(a.dir) if a.latest else a.source)
    except RecordingError as exc:
        raise UsageError(str(exc)) from None
    replay.speed = a.speed
    try:
        cfg = load_config(None)
    except ConfigError as exc:
        raise UsageError(str(exc)) from None

    live = _live_server(a.foxglove, 0.0, int(replay.meta.get("start_ns", 0) or 0))

    async def run() -> int:
        from term.ui.app import TermApp

        app = TermApp(None, config=cfg, replay=replay, live=live)
        _running[:] = [(app, asyncio.get_running_loop())]
        try:
            await app.run_async()
        finally:
            _running.clear()
            await app.shutdown()
            if live is not None:
                live.close()
        return 0

    with _terminate_on_signals():
        return asyncio.run(run())


def _recorder(args: argparse.Namespace, transport: Any, radio: Any, ble_only: bool) -> Any:
    """The session recording (term/data/recording.py) unless --no-record; its trouble is one line, never the end."""
    if args.no_record:
        return None
    import time

    from term.data.recording import SessionRecorder, default_directory

    meta = {"cable": transport.name, "radio": radio.name if radio is not None else "",
            "primary_ble": "1" if ble_only else "0"}
    rec = SessionRecorder(args.record_dir or default_directory(), time.monotonic(), meta=meta)
    if rec.error:
        print(f"term: {rec.error} (flying without a recording)", file=sys.stderr)
        return None
    return rec


def _add_foxglove(p: argparse.ArgumentParser) -> None:
    p.add_argument("--foxglove", metavar="[HOST:]PORT", default=None, help="serve the session live to Foxglove "
                   "(ws://HOST:PORT, loopback unless a host is given; needs the 'foxglove' extra); docs/recording.md")


def _live_server(address: str | None, t0: float, start_ns: int) -> Any:
    """The live Foxglove server (term/data/foxglove_server.py) if asked for; its trouble is one line, before the
    screen is taken over."""
    if address is None:
        return None
    from term.data.foxglove_server import FoxgloveError, LiveServer, parse_address

    try:
        host, port = parse_address(address)
        live = LiveServer(host, port, t0=t0, start_ns=start_ns)
    except FoxgloveError as exc:
        raise UsageError(str(exc)) from None
    print(f"Foxglove: open connection {live.url}", file=sys.stderr)
    return live


def _recordings(a: argparse.Namespace) -> int:
    from term.data.recording import default_directory, session_table

    directory = a.dir or default_directory()
    lines = session_table(directory)
    if len(lines) == 1:
        print(f"term: no session recordings in {directory}", file=sys.stderr)
        return 1
    print("\n".join(lines))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    if "_ARGCOMPLETE" in os.environ:
        _complete()
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        if argv and argv[0] == "plot":
            from term.data.plot import PlotError, plot_log
            from term.data.recording import RecordingError, latest

            a = build_plot_parser().parse_args(argv[1:])
            if a.latest == (a.log is not None):
                raise UsageError("give one recording or flight log, or --latest")
            try:
                src = latest(a.dir) if a.latest else a.log
                written = plot_log(src, a.output, a.signals.split(",") if a.signals else None, a.start, a.end,
                                   progress=_progress_bar("reading"))
            except (PlotError, RecordingError) as exc:
                raise UsageError(str(exc)) from None
            print(f"wrote {written}")
            return 0
        if argv and argv[0] == "scan":
            a = build_scan_parser().parse_args(argv[1:])
            return _scan(a)
        if argv and argv[0] == "export":
            return _export(build_export_parser().parse_args(argv[1:]))
        if argv and argv[0] == "recordings":
            return _recordings(build_recordings_parser().parse_args(argv[1:]))
        if argv and argv[0] == "replay":
            return _replay(build_replay_parser().parse_args(argv[1:]))
        if argv and argv[0] == "params":
            return _params(build_params_parser().parse_args(argv[1:]))
        return _fly(build_parser().parse_args(argv))
    except UsageError as exc:
        print(f"term: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED


def build_params_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="term params", description="The board's parameters (docs/parameters.md) over the same links as "
                "term: list them (name, value, unit, default; * changed), get or set one, save them to a TOML file, "
                "load one (only what differs is set) or diff the board against one.",
                epilog="examples: term params --sim list; term params --serial /dev/ttyUSB0 set ctrl.p1 0.45; "
                "term params --sim --preset report save report.toml")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--serial", metavar="PATH", help="the board's serial port")
    src.add_argument("--sim", action="store_true", help="start the simulated board (fcb-sim serve --pty) for this")
    p.add_argument("--ble", metavar="ADDR", help="the board's BLE address (alone: over BLE)")
    p.add_argument("--baud", type=cli_int, default=None, help="serial speed (default 115200)")
    p.add_argument("--hci", metavar="TRANSPORT", default=None, help="BLE through a bumble HCI transport")
    p.add_argument("--ble-timeout", type=cli_float, default=10.0, metavar="S", help="seconds to look for the BLE board")
    p.add_argument("--seed", type=cli_int, default=1, help="--sim: noise seed")
    p.add_argument("--preset", default=None, help="--sim: the simulated board's preset (default, report)")
    p.add_argument("--config", type=Path, default=None, help="config file (for [connection] port)")
    p.add_argument("action", help="list | get NAME | set NAME VALUE | save FILE | load FILE | diff FILE")
    p.add_argument("words", nargs="*", help="the action's NAME, VALUE or FILE")
    return p


def _params(a: argparse.Namespace) -> int:
    """term params: the link named as for flying (the config's port if none), then
    term.session.param_client.run_command."""
    from term.core.schema import SchemaError
    from term.session.config import BAUD, ConfigError, load_config
    from term.session.param_client import ParamError, run_command

    try:
        cfg = load_config(a.config, required=a.config is not None)
        baud = BAUD.check(a.baud, "--baud") if a.baud is not None else cfg.baud
        BLE_TIMEOUT.check(a.ble_timeout, "--ble-timeout")
    except (ConfigError, SchemaError) as exc:
        raise UsageError(str(exc)) from None
    _check_preset(a)
    sim: SimBoard | None = None
    try:
        if a.sim:
            sim = SimBoard(seed=a.seed, extra=["--preset", a.preset] if a.preset else [], log=True)
            transport = _serial(sim.start(), baud)
        elif a.ble and not a.serial:
            transport = _ble(a.ble, a.hci, a.ble_timeout)
        else:
            port = a.serial or cfg.port
            if not port:
                raise UsageError(f"no board given: use --serial PATH, --sim or --ble ADDR; {_ports_hint()}")
            transport = _serial(port, baud)
        try:
            return asyncio.run(run_command(transport, a.action, a.words))
        except ParamError as exc:
            raise UsageError(str(exc)) from None
    finally:
        if sim is not None:
            sim.stop()


def _check_preset(a: argparse.Namespace) -> None:
    from term.core.protocol import PRESETS
    from term.core.schema import nearest

    if a.preset is None:
        return
    if not a.sim:
        raise UsageError("--preset needs --sim (a real board keeps its parameters: 'term params load FILE')")
    if a.preset not in PRESETS:
        raise UsageError(f"unknown preset {a.preset!r}{nearest(a.preset, PRESETS)}; known: {', '.join(PRESETS)}")


# --- flying ---------------------------------------------------------------------------------------------------


def _fly_config(args: argparse.Namespace) -> tuple[Config, int]:
    """The config file with the command line's overrides, and the baud rate: one clear line if either is bad."""
    from term.core.schema import SchemaError
    from term.session.config import BAUD, LINK_TIMEOUT, ConfigError, load_config

    try:
        cfg = load_config(args.config, required=args.config is not None)
    except ConfigError as exc:
        raise UsageError(str(exc)) from None
    if args.no_bell:
        cfg.bell = False
    try:  # the same ranges as the config file's: nan, inf, 0 or a huge number is one line here
        if args.link_timeout is not None:
            cfg.link_timeout = LINK_TIMEOUT.check(args.link_timeout, "--link-timeout")
        baud = BAUD.check(args.baud, "--baud") if args.baud is not None else cfg.baud
        BLE_TIMEOUT.check(args.ble_timeout, "--ble-timeout")
    except SchemaError as exc:
        raise UsageError(str(exc)) from None
    return cfg, baud


def _check_fly_args(args: argparse.Namespace) -> None:
    """The options that do not go together, or need another, each refused in one line."""
    from term.core.logfile import check_directory

    if args.log_dir is not None and (why := check_directory(args.log_dir)):
        raise UsageError(f"--log-dir: {why}")
    if args.scenario is not None and not args.sim:
        raise UsageError("--scenario needs --sim")
    _check_preset(args)
    if args.ble and args.sim:
        raise UsageError("--ble and --sim: the simulator brings its own radio (term --sim connects it)")
    if args.board == "c":
        _check_c_board(args)
    if args.hci and not args.ble:
        raise UsageError("--hci needs --ble ADDR")
    _check_lessons(args)


def _check_c_board(args: argparse.Namespace) -> None:
    """--board c: only with --sim, and built before the simulator starts (one line if it cannot be)."""
    if not args.sim:
        raise UsageError("--board needs --sim")
    if args.preset not in (None, "default"):
        raise UsageError(f"--board c has the default preset only (docs/firmware.md), not {args.preset!r}")
    from fcb_sim.cboard import CBoardUnavailable, library_path

    try:
        library_path()
    except CBoardUnavailable as exc:
        raise UsageError(str(exc)) from None


def _fly(args: argparse.Namespace) -> int:
    from term.session.config import default_path

    if args.config_path:
        print(args.config or default_path())
        return 0
    cfg, baud = _fly_config(args)
    _check_fly_args(args)
    _start_log(args.verbose)

    sim: SimBoard | None = None
    radio: Any = None
    with _terminate_on_signals():
        try:
            if args.sim:
                c_board = args.board == "c"
                sim = SimBoard(seed=args.seed, scenario=args.scenario, link_timeout=None,
                               radio=not args.no_radio and not c_board, log=True, instructor=True)
                if args.preset:
                    sim.cmd += ["--preset", args.preset]
                if c_board:
                    sim.cmd += ["--board", "c"]
                port = sim.start()
                transport = _serial(port, baud)
                if sim.ble_address:
                    radio = _ble(sim.ble_address, sim.ble_hci, args.ble_timeout)
            elif args.ble and not args.serial:
                transport = _ble(args.ble, args.hci, args.ble_timeout)
            else:
                port = args.serial or cfg.port
                if not port:
                    raise UsageError("no board given: use --serial PATH, --sim or --ble ADDR "
                                     f"(or set [connection] port in the config); {_ports_hint()}")
                if not os.path.exists(port) and not port.upper().startswith("COM"):
                    raise UsageError(f"serial port {port} not found: check the cable and the name "
                                     "(ls /dev/tty*), or try --sim")
                transport = _serial(port, baud)
                if args.ble:
                    radio = _ble(args.ble, args.hci, args.ble_timeout)
            return asyncio.run(_run_app(transport, cfg, args, radio, sim.instructor_address if sim else ""))
        finally:
            if sim is not None:
                sim.stop()


def _serial(port: str, baud: int) -> Any:
    from term.transports.serial import SerialTransport

    return SerialTransport(port, baud)


def _ble(address: str, hci: str | None, timeout: float = 10.0) -> Any:
    """The BLE transport (term/transports/ble.py): ``BleTransport(address, hci=..., timeout=...)``."""
    try:
        from term.transports.ble import BleTransport  # type: ignore[import-not-found,unused-ignore]
    except ImportError as exc:
        raise UsageError(f"BLE transport not available ({exc})") from None
    return BleTransport(address, hci=hci, timeout=timeout)


def _scan(args: argparse.Namespace) -> int:
    _start_log(args.verbose)
    try:
        from term.transports.ble import scan  # type: ignore[import-not-found,unused-ignore]
    except ImportError as exc:
        raise UsageError(f"BLE scanning not available ({exc})") from None
    from term.core.schema import SchemaError
    from term.transports.base import TransportError

    try:
        BLE_TIMEOUT.check(args.timeout, "--timeout")
        found = asyncio.run(scan(timeout=args.timeout, hci=args.hci))
    except SchemaError as exc:
        raise UsageError(str(exc)) from None
    except TransportError as exc:
        raise UsageError(str(exc)) from None
    for board in found:
        print(board)
    if not found:
        print("term: no board found (is it powered, and advertising as Quadrupel…?)", file=sys.stderr)
        return 1
    return 0


async def _run_app(transport: Any, cfg: Any, args: argparse.Namespace, radio: Any = None,
                   instructor_address: str = "") -> int:
    from term.session.station import RADIO_SESSION
    from term.transports.base import TransportError
    from term.ui.app import TermApp

    # Fail here, in one line, before the screen is taken over: the board's link, and a radio the user named.
    # The simulator's own radio is connected by the app, which says so in its events if it cannot.
    opening = [transport] + ([radio] if radio is not None and args.ble else [])
    try:
        for t in opening:
            await t.open()
    except TransportError as exc:
        for t in opening:
            with contextlib.suppress(Exception):
                await t.close()
        raise UsageError(str(exc)) from None
    instructor = await _instructor(instructor_address, opening)
    ble_only = bool(args.ble and not args.serial)
    # Over BLE the joystick goes out on change (plus a keep-alive), as the protocol asks: the radio is slow.
    session = dict(RADIO_SESSION) if ble_only else {}
    recorder = _recorder(args, transport, radio, ble_only)
    live = _live_foxglove(args, recorder)
    sinks = tuple(s for s in (recorder, live) if s is not None)
    if sinks:  # every byte both ways on both links, tapped at the transports (term/data/recording.py); the live
        import time  # server gets the same bytes with the same times as the recording

        from term.core.events import CABLE, RADIO
        from term.data.recording import RecordingTransport

        transport = RecordingTransport(transport, sinks, CABLE, time.monotonic)
        if radio is not None:
            radio = RecordingTransport(radio, sinks, RADIO, time.monotonic)
    app = TermApp(transport, config=cfg, joystick=not args.no_joystick, log_directory=args.log_dir,
                  session_options=session, radio=radio, primary_ble=ble_only,
                  start_screen="wireless" if ble_only else "flight", recorder=recorder, instructor=instructor,
                  lesson=args.lesson, demo=args.demo, lessons_dirs=(args.lessons,) if args.lessons else (),
                  live=live)
    _running[:] = [(app, asyncio.get_running_loop())]
    hangup = asyncio.create_task(_exit_on_hangup(sys.stdin))
    try:
        result = await app.run_async()
    finally:
        _running.clear()
        hangup.cancel()
        await app.shutdown()
        for t in (transport, radio):
            if t is not None:
                with contextlib.suppress(Exception):
                    await t.close()
        if instructor is not None:
            await instructor.close()
        if recorder is not None:
            recorder.close()
        if live is not None:
            live.close()
    with contextlib.suppress(OSError, ValueError):  # (the terminal may be gone: term ended with it)
        if recorder is not None and recorder.error:
            print(f"term: {recorder.error}", file=sys.stderr)
        elif recorder is not None:
            print(f"session recorded: {recorder.path} ('term export --latest -o flight.mcap' for Foxglove)")
    if app.exit_message:
        print(f"term: {app.exit_message}", file=sys.stderr)
    code = app.return_code
    return int(code if code is not None else (result or 0))


def _live_foxglove(args: argparse.Namespace, recorder: Any) -> Any:
    """--foxglove's server on the recording's clock (a live message and the recorded one carry the same time)."""
    import time

    if recorder is not None:
        return _live_server(args.foxglove, recorder.t0, recorder.start_ns)
    return _live_server(args.foxglove, time.monotonic(), time.time_ns())


def _check_lessons(args: argparse.Namespace) -> None:
    """--lesson, --demo and --lessons: only with --sim, and a lesson that exists (its file read here, so a bad one
    is one line before the screen is taken over)."""
    wanted = args.lesson is not None or args.demo or args.lessons is not None
    if not wanted:
        return
    if not args.sim:
        raise UsageError("--lesson, --demo and --lessons need --sim: only the simulator knows where the craft is")
    if args.lesson is not None and args.demo:
        raise UsageError("--lesson or --demo, not both")
    if args.lessons is not None and not args.lessons.is_dir():
        raise UsageError(f"--lessons {args.lessons}: not a directory")
    from term.input.keymap import DEFAULT_KEYMAP
    from term.lessons.spec import DEMO, LessonError, load_lessons, load_script

    actions = [b.action.name for b in DEFAULT_KEYMAP]
    if args.demo:
        try:
            load_script(DEMO, actions)
        except LessonError as exc:
            raise UsageError(str(exc)) from None
    if args.lesson is not None:
        lessons, skipped = load_lessons((args.lessons,) if args.lessons else (), actions)
        if args.lesson not in lessons:
            bad = next((s for s in skipped if f"{args.lesson:02d}" in s.split(":")[0]), "")
            raise UsageError(bad or f"no lesson {args.lesson}; there are {', '.join(map(str, lessons)) or 'none'}")


async def _instructor(address: str, opening: list[Any]) -> Any:
    """The simulator's instructor channel (term/lessons/instructor.py), open; None without one."""
    if not address:
        return None
    from term.lessons.instructor import InstructorClient

    client = InstructorClient(address)
    try:
        await client.open()
    except (OSError, TimeoutError, ValueError) as exc:
        for t in opening:
            with contextlib.suppress(Exception):
                await t.close()
        raise UsageError(f"the simulated board's instructor channel {address}: {exc}") from None
    return client


# The app while it runs, and its loop: a signal asks it to exit through the loop.
_running: list[tuple[Any, asyncio.AbstractEventLoop]] = []
SIGNAL_EXIT_GRACE_S = 5.0  # after a signal, the longest an orderly exit may take before term ends itself


@contextlib.contextmanager
def _terminate_on_signals() -> Any:
    """SIGTERM and SIGHUP (terminal closed) end term in order, so the child board is stopped on the way out.

    While the app runs, the signal asks it to exit through its event loop: unwinding with SystemExit from inside
    the loop would skip Textual's own shutdown and leave its input thread spinning on a dead terminal, keeping
    the process alive. A watchdog ends the process if the orderly exit hangs (the child board then gets its own
    SIGTERM from the kernel, PR_SET_PDEATHSIG)."""
    def raise_exit(signum: int, frame: object) -> None:
        if not _request_exit(128 + signum):
            raise SystemExit(128 + signum)

    old = {}
    # getattr: Windows has no SIGHUP (a closed console window ends the process there anyway)
    for sig in (getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name)):
        with contextlib.suppress(ValueError, OSError):
            old[sig] = signal.signal(sig, raise_exit)
    try:
        yield
    finally:
        for sig, handler in old.items():
            with contextlib.suppress(ValueError, OSError):
                signal.signal(sig, handler)


def _request_exit(code: int) -> bool:
    """Ask the running app to exit in order with ``code`` (False if none runs); end the process if that hangs."""
    if not _running:
        return False
    app, loop = _running[0]
    watchdog = threading.Timer(SIGNAL_EXIT_GRACE_S, os._exit, (code,))
    watchdog.daemon = True
    watchdog.start()
    loop.call_soon_threadsafe(lambda: app.exit(return_code=code))
    return True


async def _exit_on_hangup(stream: IO[str], period: float = 0.5) -> None:
    """Exit when the terminal goes away. Closing a terminal does not always signal us (a session leader that
    ignores SIGHUP does not pass it on), and Textual reads a hung-up terminal's EOF as piped input and keeps
    running; a hung-up tty reports POLLHUP, which polling sees without taking any input."""
    try:
        fd = stream.fileno()
    except (AttributeError, OSError, ValueError):
        return
    if not os.isatty(fd) or not hasattr(select, "poll"):  # no poll() on Windows: the console ends us itself
        return
    poller = select.poll()
    poller.register(fd, 0)  # POLLHUP and POLLERR are reported whatever is asked for
    while True:
        await asyncio.sleep(period)
        if any(ev & (select.POLLHUP | select.POLLERR | select.POLLNVAL) for _, ev in poller.poll(0)):
            _request_exit(128 + signal.SIGHUP)
            return


if __name__ == "__main__":
    sys.exit(main())
