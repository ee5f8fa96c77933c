"""`term --ble` on the command line: every failure to reach the board is one line and exit 2, never a traceback;
and `term --ble` against the simulator's radio (a real `fcb-sim serve --ble-hci` child) opens the wireless screen,
waits for the handover, and, when the radio goes away, says so and reconnects by itself."""

from __future__ import annotations

import socket
import subprocess
import sys
from collections.abc import Iterator

import pytest

from term.cli.main import main
from term.session.sim import SimBoard
from tests.support.waits import until


@pytest.fixture(autouse=True)
def a_terminal(monkeypatch: pytest.MonkeyPatch) -> None:
    """As if term ran in a terminal (pytest's stdin is none): the link's own failures come after that check."""
    monkeypatch.setattr("term.cli.main.has_terminal", lambda: True)


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str]:
    code = main([*argv, "--no-joystick"])
    return code, capsys.readouterr().err


def one_line(err: str) -> None:
    assert err.startswith("term: ") and err.count("\n") == 1 and "Traceback" not in err, err


@pytest.fixture(scope="module")
def sim() -> Iterator[SimBoard]:
    board = SimBoard(seed=2, radio=True)
    board.start()
    try:
        yield board
    finally:
        board.stop()


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize("argv, words", [
    (["--ble", "F0:5A:00:00:00:01", "--sim"], "--ble and --sim"),
    (["--serial", "/dev/null", "--hci", "usb:0"], "--hci needs --ble ADDR"),
    (["--ble", "F0:5A:00:00:00:01", "--ble-timeout", "0"], "--ble-timeout: must be a number between 0.1 and 600 s"),
    # the address before the adapter (issue 25: 'nonsense' got "no Bluetooth adapter reachable")
    (["--ble", "nonsense"], "--ble 'nonsense' is not a Bluetooth address: six hex pairs such as F0:5A:00:00:00:01"),
    (["--ble", "F0:5A:00:00:00:0G", "--hci", "usb:0"], "is not a Bluetooth address"),
    (["--serial", "/dev/null", "--ble", "F0:5A:00:00:00"], "is not a Bluetooth address"),
])
def test_option_errors(capsys: pytest.CaptureFixture[str], argv: list[str], words: str) -> None:
    code, err = run(capsys, *argv)
    assert code == 2 and words in err
    one_line(err)


def test_no_adapter_at_the_hci_transport(capsys: pytest.CaptureFixture[str]) -> None:
    port = free_port()  # nobody listens there: no controller
    code, err = run(capsys, "--ble", "F0:5A:00:00:00:01", "--hci", f"tcp-client:127.0.0.1:{port}")
    assert code == 2 and f"cannot open the Bluetooth adapter tcp-client:127.0.0.1:{port}" in err
    assert "check --hci" in err
    one_line(err)


def test_no_platform_bluetooth(capsys: pytest.CaptureFixture[str]) -> None:
    """Without --hci the platform's stack (BlueZ over D-Bus here): on this machine there is none."""
    code, err = run(capsys, "--ble", "AA:BB:CC:DD:EE:FF", "--ble-timeout", "1")
    if code == 0:
        pytest.skip("this machine has a Bluetooth stack")
    assert code == 2 and ("Bluetooth" in err or "no board with address" in err)
    one_line(err)


def test_an_unknown_address(capsys: pytest.CaptureFixture[str], sim: SimBoard) -> None:
    code, err = run(capsys, "--ble", "F0:5A:00:00:00:99", "--hci", sim.ble_hci, "--ble-timeout", "1")
    assert code == 2 and "no board with address F0:5A:00:00:00:99 found nearby" in err and "term scan" in err
    one_line(err)


def test_an_unknown_address_beside_the_cable(capsys: pytest.CaptureFixture[str], sim: SimBoard) -> None:
    """A radio the user named must be there, even beside a cable that works."""
    code, err = run(capsys, "--serial", sim.port, "--ble", "F0:5A:00:00:00:98", "--hci", sim.ble_hci,
                    "--ble-timeout", "1")
    assert code == 2 and "no board with address F0:5A:00:00:00:98" in err
    one_line(err)


def test_scan_finds_the_simulator(sim: SimBoard) -> None:
    out = subprocess.run([sys.executable, "-m", "term.cli.main", "scan", "--hci", sim.ble_hci, "--timeout", "1"],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and f"{sim.ble_name}" in out.stdout and sim.ble_address in out.stdout


async def test_ble_alone_waits_for_the_handover_and_reconnects_a_lost_radio() -> None:
    """The app as `term --ble ADDR --hci T` builds it: BLE the only link, on the wireless screen. Before the
    handover the board says nothing over BLE: that is no alarm. The radio's HCI transport drops: one visible
    LINK LOST line, then it is connected again (a pause, then a retry) without the pilot doing anything."""
    from term.session.station import RADIO_SESSION
    from term.transports.ble import BleTransport
    from term.ui.app import TermApp
    from term.ui.screens.wireless import WirelessScreen

    sim = SimBoard(seed=5, radio=True)
    sim.start()
    try:
        transport = BleTransport(sim.ble_address, hci=sim.ble_hci, timeout=5.0)
        await transport.open()
        app = TermApp(transport, joystick=False, session_options=dict(RADIO_SESSION), primary_ble=True,
                      start_screen="wireless")
        async with app.run_test(size=(100, 32)) as pilot:
            m = app.model

            assert isinstance(app.screen, WirelessScreen)
            await until(pilot, lambda: m.link_lost)  # silent: the board talks over BLE only after the handover
            assert not m.control_lost and "waiting for the handover" in m.events[-1].text + str(
                app.screen.query_one("#w-telemetry").render())
            hci = transport._client._backend._host.transport  # the radio dies (on the link's thread, where it runs)
            await app.station.runner.run(hci.close()) if app.station.runner is not None else await hci.close()
            await until(pilot, lambda: any(e.text.startswith("LINK LOST: BLE connection") for e in m.events))
            assert app.connection is None
            await until(pilot, lambda: any(e.text.startswith("reconnected to BLE") for e in m.events))
            assert app.connection is not None
        await transport.close()
    finally:
        sim.stop()
