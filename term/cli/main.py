# PYTHON_ARGCOMPLETE_OK (shell completion: eval "$(register-python-argcomplete term)")
"""`term`: the pilot's terminal from the command line. Parsing and wiring only; the one place that knows every part.

    term --serial /dev/ttyUSB0 [--baud 115200]    fly the real board (or any pty)
    term --sim [--seed N] [--scenario NAME]       start `fcb-sim serve --pty --ble-hci ...` and fly it over that
                                                  real pty, its radio connected too (key 8 hands over to BLE);
                                                  without pseudo-terminals (Windows) or with --sim-link tcp, over
                                                  a loopback TCP port (socket://, the same serial transport)
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

The parser is term/cli/parser.py: one argparse parser with a subparser per command, which shell completion reads
too; -v and --version are taken before and after a command. The screens (flying, replay) need a terminal on stdin
and stdout: without one they say so in one line and exit 2, before anything is started.

term's own log (warnings always, everything with --verbose) and the simulated board's stderr are kept in the
platform's log directory (term/session/applog.py): the TUI owns the terminal, so nothing can be printed while it runs.
POSIX-only parts (SIGHUP, the hung-up-tty watcher, the child's PR_SET_PDEATHSIG) are skipped where missing; the
watcher uses what each platform reports (macOS: no poll() on terminals): term/cli/signals.py, which also makes a
signal in flight take Ctrl+Q's path (PANIC first).

Errors a user can cause end in one line on stderr and a non-zero exit, never a traceback: 2 for bad arguments,
a missing port or a board that will not start; 3 for a board that speaks another protocol version.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import sys
import threading
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from term.cli.parser import build_parser, check_command, complete, serial_ports, version_text
from term.cli.signals import _exit_on_hangup, _running, _terminate_on_signals
from term.core.errors import EXIT_INTERRUPTED, EXIT_USAGE, EXIT_VERSION, UsageError
from term.core.schema import Number
from term.session.links import LinkSpec, open_link
from term.session.sim import SimBoard

if TYPE_CHECKING:
    from term.session.config import Config

__all__ = ["EXIT_USAGE", "EXIT_VERSION", "UsageError", "build_parser", "main", "version_text"]

BLE_TIMEOUT = Number(0.1, 600.0, unit="s")  # --ble-timeout, scan --timeout: seconds to look for the board
# A BLE address as the platforms name one: six hex pairs (BlueZ, Windows, bumble), or CoreBluetooth's UUID (macOS)
BLE_ADDRESS = re.compile(r"[0-9A-Fa-f]{2}(:[0-9A-Fa-f]{2}){5}|[0-9A-Fa-f]{8}(-[0-9A-Fa-f]{4}){3}-[0-9A-Fa-f]{12}")


def has_terminal() -> bool:
    """Both stdin and stdout are a terminal: the screen reads keys from one and draws on the other."""
    try:
        return sys.stdin is not None and sys.stdout is not None and sys.stdin.isatty() and sys.stdout.isatty()
    except (AttributeError, ValueError):  # a closed or replaced stream
        return False


def _need_terminal() -> None:
    """Every screen (flying, replay) refuses to start without a terminal, in one line, before anything starts."""
    if not has_terminal():
        raise UsageError("no terminal: the screen needs one on stdin and stdout (run term in a terminal; "
                         "'term plot', 'export' and 'params' work without)")


def _plain_on_dumb_terminals() -> None:
    """TERM=dumb gets the screen as NO_COLOR does (Textual honours NO_COLOR: monochrome) in the 16 basic colours:
    Textual draws in 24-bit colour when it detects no colour system, as for a dumb terminal. Set before textual is
    first imported (its constants are read then), so at the start of main."""
    if os.environ.get("TERM") == "dumb":
        os.environ.setdefault("NO_COLOR", "1")
        os.environ.setdefault("TEXTUAL_COLOR_SYSTEM", "standard")


def _ports_hint() -> str:
    ports = serial_ports()
    if not ports:
        return "no serial ports seen here"
    return "serial ports seen here: " + ", ".join(
        device if desc in ("", "n/a", device) else f"{device} ({desc})" for device, desc in ports
    )


def _check_ble_address(address: str | None) -> None:
    """The address's form before any adapter is asked for: 'nonsense' is named as what it is."""
    if address is not None and not BLE_ADDRESS.fullmatch(address):
        raise UsageError(f"--ble {address!r} is not a Bluetooth address: six hex pairs such as F0:5A:00:00:00:01 "
                         "(on macOS the board's UUID); 'term scan' lists the boards nearby")


def _start_log(verbose: bool) -> None:
    from term.session.applog import setup_logging

    path = setup_logging(verbose)
    if verbose and path is not None:
        print(f"term: logging to {path}", file=sys.stderr)


def _export(a: argparse.Namespace) -> int:
    from term.data.export import ExportError, export
    from term.data.recording import RecordingError, latest

    _start_log(a.verbose)
    if a.latest == (a.source is not None):
        raise UsageError("give one recording or flash log, or --latest")
    if not a.output.parent.exists():  # made, and said (issue 34: it was made without a word)
        try:
            a.output.parent.mkdir(parents=True)
        except OSError as exc:
            raise UsageError(f"cannot make folder {a.output.parent}: {exc.strerror or exc}") from None
        print(f"term: made folder {a.output.parent} for {a.output.name}", file=sys.stderr)
    try:
        src = latest(a.dir) if a.latest else a.source
        res = export(src, a.output, a.format, a.board_units, raw=a.raw, progress=_progress_bar("exporting"))
    except (ExportError, RecordingError) as exc:
        raise UsageError(str(exc)) from None
    what = "frames and events" if res.kind == "session" else "records"
    cut = "" if res.complete else " (the recording was cut short: all of it that was on disk)"
    print(f"wrote {a.output}: {res.rows} {what} from {src}{cut}")
    for line in res.damage:  # the rest was exported; the exit status says not all of it was readable
        print(f"term export: damage skipped: {line}", file=sys.stderr)
    return 1 if res.damage else 0


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


def _replay(a: argparse.Namespace) -> int:
    import asyncio  # (not at the top: 'term params --sim' starts its board before this)

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
        cfg = load_config(a.config, required=a.config is not None)
    except ConfigError as exc:
        raise UsageError(str(exc)) from None
    _start_log(a.verbose)

    # (its one-line errors first)
    live = _live_server(a.foxglove, 0.0, int(replay.meta.get("start_ns", 0) or 0), a.foxglove_public)
    try:
        _need_terminal()
    except UsageError:
        if live is not None:
            live.close()
        raise

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
    if rec.error:  # the app shows it at once, as an alarm (the screen covers this line)
        print(f"term: {rec.error} (flying without a recording)", file=sys.stderr)
    return rec


def _live_server(address: str | None, t0: float, start_ns: int, public: bool = False) -> Any:
    """The live Foxglove server (term/data/foxglove_server.py) if asked for; its trouble is one line, before the
    screen is taken over."""
    if address is None:
        return None
    from term.data.foxglove_server import FoxgloveError, LiveServer, parse_address, public_refusal

    try:
        host, port = parse_address(address)
        why = public_refusal(host, public)
        if why:
            raise FoxgloveError(why)
        live = LiveServer(host, port, t0=t0, start_ns=start_ns)
    except FoxgloveError as exc:
        raise UsageError(str(exc)) from None
    print(f"Foxglove: open connection {live.url}", file=sys.stderr)
    return live


def _recordings(a: argparse.Namespace) -> int:
    from term.data.recording import default_directory, session_table

    _start_log(a.verbose)
    if a.dir is not None and not a.dir.is_dir():  # a folder named wrong: a usage error, as export's (2)
        raise UsageError(f"no session recordings in {a.dir}: no such folder")
    directory = a.dir or default_directory()
    lines = session_table(directory)
    if len(lines) == 1:
        print(f"term: no session recordings in {directory}", file=sys.stderr)
        return 1
    print("\n".join(lines))
    return 0


def _plot(a: argparse.Namespace) -> int:
    from term.data.plot import PlotError, plot_log
    from term.data.recording import RecordingError, latest

    _start_log(a.verbose)
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


def run() -> None:
    """The ``term`` command (and ``python -m term``): ``main``, then an exit that skips the interpreter's teardown
    (term/session/quick_exit.py: freeing Textual's and bumble's objects one by one made quitting slow)."""
    from term.session.quick_exit import exit_now

    exit_now(main())


def main(argv: Sequence[str] | None = None) -> int:
    _plain_on_dumb_terminals()
    parser = build_parser()
    if "_ARGCOMPLETE" in os.environ:
        complete(parser)
    try:
        args = parser.parse_args(argv)
        check_command(parser, args)
        handlers = {None: _fly, "plot": _plot, "scan": _scan, "export": _export, "recordings": _recordings,
                    "replay": _replay, "params": _params}
        return handlers[args.command](args)
    except UsageError as exc:
        print(f"term: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED


def _params(a: argparse.Namespace) -> int:
    """term params: the link named as for flying (the config's port if none), then
    term.session.param_client.run_command."""
    from term.core.schema import SchemaError

    try:
        if a.baud is not None:
            from term.session.config import BAUD

            BAUD.check(a.baud, "--baud")
        BLE_TIMEOUT.check(a.ble_timeout, "--ble-timeout")
    except SchemaError as exc:
        raise UsageError(str(exc)) from None
    _check_preset(a)
    if a.action is None:  # (argparse would name its 'words' as missing)
        raise UsageError("give an action: list | get NAME | set NAME VALUE | save FILE | load FILE | diff FILE")
    if a.sim and (a.serial or a.ble):  # (one may stand before 'params' and the other after it)
        raise UsageError("--sim brings its own board: not with --serial or --ble")
    _check_sim_link(a)
    _check_ble_address(a.ble)
    sim: SimBoard | None = None
    try:
        if a.sim:  # the board boots on the other core while the config is read and the client imported
            sim = SimBoard(seed=a.seed, extra=["--preset", a.preset] if a.preset else [], log=True,
                           link=a.sim_link)
            sim.launch()
        _start_log(a.verbose)
        return _params_on(a, sim)
    finally:
        if sim is not None:
            sim.stop()


def _params_on(a: argparse.Namespace, sim: SimBoard | None) -> int:
    """``term params`` once the simulated board (if any) is launched: the config, the link, the command."""
    import asyncio  # (not at the top: 'term params --sim' starts its board before this)

    from term.core.schema import SchemaError
    from term.session.config import BAUD, ConfigError, load_config
    from term.session.param_client import ParamError, run_command

    try:
        cfg = load_config(a.config, required=a.config is not None)
        baud = BAUD.check(a.baud, "--baud") if a.baud is not None else cfg.baud
    except (ConfigError, SchemaError) as exc:
        raise UsageError(str(exc)) from None
    if sim is not None:
        sim.start()
        transport = sim.transport(baud)
    else:
        port = None if a.ble and not a.serial else a.serial or cfg.port
        if not port and not a.ble:
            raise UsageError(f"no board given: use --serial PATH, --sim or --ble ADDR; {_ports_hint()}")
        spec = LinkSpec(port=port, baud=baud, ble=a.ble, hci=a.hci, ble_timeout=a.ble_timeout)
        transport = open_link(spec)  # the cable when a port is named, else BLE: as for flying
    try:
        return asyncio.run(run_command(transport, a.action, a.words))
    except ParamError as exc:
        raise UsageError(str(exc)) from None


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
    _check_sim_link(args)
    _check_preset(args)
    if args.ble and args.sim:
        raise UsageError("--ble and --sim: the simulator brings its own radio (term --sim connects it)")
    if args.board == "c":
        _check_c_board(args)
    if args.hci and not args.ble:
        raise UsageError("--hci needs --ble ADDR")
    _check_ble_address(args.ble)
    _check_lessons(args)
    if args.mavlink_public and args.mavlink is None:
        raise UsageError("--mavlink-public needs --mavlink")
    if args.mavlink is not None:
        from term.data.mavlink import MavlinkError, parse_address

        try:
            parse_address(args.mavlink, args.mavlink_public)
        except MavlinkError as exc:
            raise UsageError(str(exc)) from None


def _check_sim_link(args: argparse.Namespace) -> None:
    """--sim-link: only with --sim; pty only where there are pseudo-terminals (one line naming tcp)."""
    if args.sim_link is None:
        return
    if not args.sim:
        raise UsageError("--sim-link needs --sim (a real board's link is --serial: a device or socket://HOST:PORT)")
    from term.session.sim import pty_missing

    if args.sim_link == "pty" and (why := pty_missing()):
        raise UsageError(f"--sim-link pty: {why}; use --sim-link tcp (the board on a loopback TCP port)")


def _check_c_board(args: argparse.Namespace) -> None:
    """--board c: only with --sim, and built before the simulator starts (one line if it cannot be)."""
    if not args.sim:
        raise UsageError("--board needs --sim")
    from term.session.sim import c_board_problem

    problem = c_board_problem()
    if problem:
        raise UsageError(problem)


def _cable(args: argparse.Namespace, cfg: Config) -> str | None:
    """The serial port to fly over (None for --sim or BLE alone), checked before anything starts."""
    if args.sim or (args.ble and not args.serial):
        return None
    port = args.serial or cfg.port
    if not port:
        raise UsageError("no board given: use --serial PATH, --sim or --ble ADDR "
                         f"(or set [connection] port in the config); {_ports_hint()}")
    if "://" not in port and not os.path.exists(port) and not port.upper().startswith("COM"):
        raise UsageError(f"serial port {port} not found: check the cable and the name (ls /dev/tty*), or try --sim")
    return port


def _fly(args: argparse.Namespace) -> int:
    import asyncio  # (not at the top: 'term params --sim' starts its board before this)

    from term.session.config import default_path

    if args.config_path:
        print(args.config or default_path())
        return 0
    cfg, baud = _fly_config(args)
    _check_fly_args(args)
    port = _cable(args, cfg)
    _need_terminal()
    _start_log(args.verbose)

    sim: SimBoard | None = None
    radio: Any = None
    with _terminate_on_signals():
        try:
            if args.sim:
                c_board = args.board == "c"
                sim = SimBoard(seed=args.seed, scenario=args.scenario, link_timeout=None,
                               radio=not args.no_radio and not c_board, log=True, instructor=True,
                               link=args.sim_link)
                if args.preset:
                    sim.cmd += ["--preset", args.preset]
                if c_board:
                    sim.cmd += ["--board", "c"]
                screens = _import_in_background("term.ui.app")  # while the board starts: each takes seconds
                sim.start()
                screens.join()
                transport = sim.transport(baud)
                if sim.ble_address:
                    radio = open_link(LinkSpec(ble=sim.ble_address, hci=sim.ble_hci, ble_timeout=args.ble_timeout))
            else:
                spec = LinkSpec(port=port, baud=baud, ble=args.ble, hci=args.hci, ble_timeout=args.ble_timeout)
                transport = open_link(spec)  # the cable, or BLE alone
                if spec.cable is not None and spec.radio is not None:
                    radio = open_link(spec.radio)  # the radio beside the cable, for the handover
            return asyncio.run(_run_app(transport, cfg, args, radio, sim.instructor_address if sim else ""))
        finally:
            if sim is not None:
                sim.stop()


def _import_in_background(module: str) -> threading.Thread:
    """Import ``module`` (Textual and the screens) on a thread while the main one waits for the simulated board:
    the child boots on the other core. Join it before importing anything else (two threads importing the same
    modules can deadlock on their locks); what SimBoard.start imports is imported first, here."""
    import importlib

    import platformdirs  # noqa: F401  (SimBoard.start's own imports, done before the thread's)

    import term.session.applog  # noqa: F401

    def run() -> None:
        with contextlib.suppress(Exception):  # a failure shows again where the app is imported, in one line
            importlib.import_module(module)

    thread = threading.Thread(target=run, name=f"import {module}", daemon=True)
    thread.start()
    return thread


def _scan(args: argparse.Namespace) -> int:
    import asyncio  # (not at the top: 'term params --sim' starts its board before this)

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
    import asyncio  # (not at the top: 'term params --sim' starts its board before this)

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
    mavlink = _mavlink(args, recorder)
    transport, radio = _tapped(transport, radio, tuple(s for s in (recorder, live) if s is not None))
    app = TermApp(transport, config=cfg, joystick=not args.no_joystick, log_directory=args.log_dir,
                  session_options=session, radio=radio, primary_ble=ble_only,
                  start_screen="wireless" if ble_only else "flight", recorder=recorder, instructor=instructor,
                  lesson=args.lesson, demo=args.demo, lessons_dirs=(args.lessons,) if args.lessons else (),
                  live=live, mavlink=mavlink)
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
        if mavlink is not None:
            mavlink.close()
    with contextlib.suppress(OSError, ValueError):  # (the terminal may be gone: term ended with it)
        if recorder is not None and recorder.error:
            print(f"term: {recorder.error}", file=sys.stderr)
        elif recorder is not None:
            print(f"session recorded: {recorder.path} ('term export --latest -o flight.mcap' for Foxglove)")
    if app.exit_message:
        print(f"term: {app.exit_message}", file=sys.stderr)
    code = app.return_code
    return int(code if code is not None else (result or 0))


def _tapped(transport: Any, radio: Any, sinks: tuple[Any, ...]) -> tuple[Any, Any]:
    """Every byte both ways on both links, tapped at the transports for the sinks (term/data/recording.py): the
    live server has the same times as the recording (and the same bytes: what it reads is decoded by the links)."""
    if not sinks:
        return transport, radio
    import time

    from term.core.events import CABLE, RADIO
    from term.data.recording import RecordingTransport

    transport = RecordingTransport(transport, sinks, CABLE, time.monotonic)
    if radio is not None:
        radio = RecordingTransport(radio, sinks, RADIO, time.monotonic)
    return transport, radio


def _live_foxglove(args: argparse.Namespace, recorder: Any) -> Any:
    """--foxglove's server on the recording's clock (a live message and the recorded one carry the same time)."""
    import time

    if recorder is not None:
        return _live_server(args.foxglove, recorder.t0, recorder.start_ns, args.foxglove_public)
    return _live_server(args.foxglove, time.monotonic(), time.time_ns(), args.foxglove_public)


# --- term --mavlink (term/data/mavlink.py; helper mavlink) ---
def _mavlink(args: argparse.Namespace, recorder: Any) -> Any:
    """--mavlink's endpoint on the recording's clock (its time_boot_ms is the session's time); its trouble is one
    line, before the screen is taken over."""
    if getattr(args, "mavlink", None) is None:
        return None
    import time

    from term.data.mavlink import MavlinkEndpoint, MavlinkError

    try:
        endpoint = MavlinkEndpoint(args.mavlink, t0=recorder.t0 if recorder is not None else time.monotonic(),
                                   public=args.mavlink_public)
    except MavlinkError as exc:
        raise UsageError(str(exc)) from None
    print(f"MAVLink: sending to {endpoint.url}", file=sys.stderr)
    return endpoint


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


if __name__ == "__main__":
    sys.exit(main())
