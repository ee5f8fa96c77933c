"""The link panel: RTT, loss, bytes/s, frame errors, time since the last heartbeat, and a clear LINK LOST; its
bottom border names the board as its Hello did (id, firmware and protocol version)."""

from __future__ import annotations

from rich.console import RenderableType
from rich.text import Text

from term.core.protocol import Hello, WirelessState
from term.session.model import Model
from term.session.texts import rtt_text
from term.ui.screens.wireless import link_lines
from term.ui.widgets.base import ModelView

NARROW_COLS = 45  # a panel narrower than this (80 columns: 36) gets one line a link, cut to fit, never cut by the edge


def _ms(v: float | None) -> str:
    return "—" if v is None else f"{v:.1f}"


def _heartbeat(model: Model, name: str, age: float | None) -> str:
    """The heartbeat's age, unless the link is quiet by design (then it would only count up): the radio before the
    handover and after it ends, the cable while the board flies over BLE."""
    quiet = model.wireless == WirelessState.DISCONNECTED if name == "ble" else model.over_ble
    if quiet:
        return "— (idle)" if name == "ble" else "— (over BLE)"
    return "—" if age is None else f"{age * 1000:.0f} ms ago"


def board_text(hello: Hello | None, width: int = 80) -> str:
    """The board as its last Hello named it, in at most ``width`` characters where it can: "board 1 · fw 0.1 ·
    protocol v4", narrower "#1 · fw 0.1 · protocol v4" ("" before any Hello)."""
    if hello is None:
        return ""
    version = f"fw {hello.major}.{hello.minor} · protocol v{hello.protocol}"
    full = f"board {hello.board_id} · {version}"
    return full if len(full) <= width else f"#{hello.board_id} · {version}"


class LinkPanel(ModelView):
    TIME_DEPENDENT = True  # ages grow without new data
    MAX_HZ = 4.0  # statistics; but LINK LOST and its end show at once

    def urgent(self, model: Model) -> object:
        return (model.link_lost, model.link is None or model.link.since_last_frame_s is None, model.control_lost,
                model.over_ble, model.radio_up, model.radio_lost)

    def render_model(self, model: Model, now: float) -> RenderableType:
        # in the bottom border (the panel's rows are all taken), between its corners and the title's padding
        live = f"Foxglove {model.live_url}" if model.live_url else ""
        board = board_text(model.hello, self.size.width - 6 - (len(live) + 3 if live else 0))
        self.subtitle(" · ".join(t for t in (board, live) if t))
        if model.radio_name:
            return self._two_links(model)
        s = model.link
        out = Text()
        if model.primary_ble and not model.heard:
            out.append("BLE connected: waiting for the handover\n", style="yellow")
            out.append("(the board talks over BLE after key 8 on the cable terminal, in SAFE)\n", style="dim")
        elif model.control_lost:
            out.append("  L I N K   L O S T  ", style="bold blink white on red")
            out.append("\n")
            if model.handed_over:
                out.append("the board was handing over to BLE (key 8): it may be talking there now\n",
                           style="yellow")
        elif s is None or s.since_last_frame_s is None:
            out.append("waiting for the board…", style="yellow")
            out.append("\n")
        else:
            out.append("link OK", style="bold green")
            out.append(f"  {model.link_name}\n" if model.link_name else "\n", style="dim")
        if s is None:
            return out
        out.append(f"RTT  {_ms(s.rtt_last_ms)} ms  mean {_ms(s.rtt_mean_ms)}  p95 {_ms(s.rtt_p95_ms)}\n")
        loss = "—" if s.loss_pct is None else f"{s.loss_pct:.1f}"
        loss_style = "red" if s.loss_pct and s.loss_pct > 5 else ""
        out.append(f"loss {loss} % (total {s.loss_pct_total:.1f} %)\n", style=loss_style)
        out.append(f"rx {s.rx_bytes_per_s:7.0f} B/s  tx {s.tx_bytes_per_s:6.0f} B/s\n")
        out.append(f"frames ok {s.frames_ok}  bad ", style="")
        out.append(f"{s.frames_bad}", style="red" if s.frames_bad else "")
        out.append(f"  retries {s.command_retries}  failed {s.commands_failed}\n")
        hb = s.since_last_heartbeat_s
        hb_style = "red" if hb is None or hb > 0.5 else ""
        out.append(f"heartbeat {'—' if hb is None else f'{hb * 1000:.0f} ms ago'}", style=hb_style)
        if s.heartbeat_delay_ms is not None:
            out.append(f"  delay {s.heartbeat_delay_ms:.1f} ms")
        return out

    def _two_links(self, model: Model) -> Text:
        """The cable and the radio: which carries control (▶), each one's health, then the figures of both."""
        out = Text()
        if model.link_name.startswith("REPLAY "):  # term replay: say so above the recorded links
            out.append(f"{model.link_name}\n", style="bold yellow")
        if model.control_lost:
            out.append("  L I N K   L O S T  ", style="bold blink white on red")
            out.append("  (the link that carries control)\n", style="red")
        width = self.content_size.width or 80
        narrow = width < NARROW_COLS
        link_lines(model, out, width if narrow else None)
        for name, s in (("cable", model.link), ("ble", model.radio if model.radio_up else None)):
            if s is None:
                continue
            hb = s.since_last_heartbeat_s
            loss = "—" if s.loss_pct is None else f"{s.loss_pct:.1f}"
            if narrow:  # one line a link, the figures a pilot reads in flight: the rest where it fits (issue 34)
                beat = _heartbeat(model, name, hb).replace(" ago", "").replace(" (idle)", "").replace(
                    " (over BLE)", "")
                rtt = rtt_text(s) or "RTT —"  # (the one RTT the screens show: none for an idle link)
                out.append(f"{name:<6}{rtt}  loss {loss}%  hb {beat}\n"[:width + 1],
                           style="dim" if model.over_ble != (name == "ble") else "")
                continue
            out.append(f"{name:<6}{rtt_text(s) or 'RTT —'}  loss {loss}%  rx/tx {s.rx_bytes_per_s:.0f}/"
                       f"{s.tx_bytes_per_s:.0f}\n", style="dim" if model.over_ble != (name == "ble") else "")
            out.append(f"      frames {s.frames_ok} bad {s.frames_bad}  heartbeat {_heartbeat(model, name, hb)}\n",
                       style="dim")
        return out
