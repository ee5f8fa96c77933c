"""What happens at the ground station, as plain events: the vocabulary between the station (which emits them), the
model (which applies them, ``Model.apply``: the one place it changes) and a front end (which reacts to some: a
toast for a refusal, exiting on ``Fatal``).

A link's own session events (``term.core.link``: packets, acks, loss) travel wrapped in ``FromLink`` with the link
they came over: ``CABLE`` (the board's link: serial, or BLE alone with ``term --ble``) or ``RADIO`` (BLE beside
the cable, for the handover). The rest are the station's (links up and down, retries, commands sent or refused,
the stick) and the front end's own (notes, the hardware joystick's name, clearing the events list).
No I/O, no Textual, no clock: plain frozen data.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from term.core.link import LinkEvent, LinkStats
from term.core.protocol import Joystick

CABLE = "cable"
RADIO = "radio"



@dataclass(frozen=True, slots=True)
class FromLink:
    """An event of one link's session (packets, acks, loss): ``link`` is CABLE or RADIO."""

    link: str
    event: LinkEvent


@dataclass(frozen=True, slots=True)
class LinkUp:
    link: str
    name: str  # the transport's name
    again: bool  # a reconnection, not the first connection


@dataclass(frozen=True, slots=True)
class LinkDown:
    """The link's transport died (a cable pulled, the radio out of range); it will be tried again."""

    link: str
    message: str


@dataclass(frozen=True, slots=True)
class LinkWaiting:
    """The next try of a dead link is ``pause`` seconds away; ``why`` is the last failure ("" if none)."""

    link: str
    why: str
    pause: float


@dataclass(frozen=True, slots=True)
class LinkConnecting:
    link: str


@dataclass(frozen=True, slots=True)
class LinkFailed:
    """One try to connect failed; ``repeated``: the same reason as the try before (not worth saying again)."""

    link: str
    message: str
    repeated: bool


@dataclass(frozen=True, slots=True)
class StatsSample:
    link: str
    stats: LinkStats


@dataclass(frozen=True, slots=True)
class Requested:
    """A command left for the board over ``link``."""

    op: int
    arg: int
    link: str


@dataclass(frozen=True, slots=True)
class NotSent:
    """A command the station refused to send; ``title`` set: worth a toast as well as the events list."""

    what: str
    why: str
    title: str | None = None
    severity: Literal["information", "warning", "error"] = "error"  # the toast's


@dataclass(frozen=True, slots=True)
class Note:
    severity: str  # "info", "warning", "error"
    source: str
    text: str


@dataclass(frozen=True, slots=True)
class StickSet:
    stick: Joystick


@dataclass(frozen=True, slots=True)
class JoystickNamed:
    """The hardware joystick plugged in (its name and mapping) or gone (``name`` None)."""

    name: str | None
    mapping: str


@dataclass(frozen=True, slots=True)
class EventsCleared:
    pass


@dataclass(frozen=True, slots=True)
class Fatal:
    """Nothing more can be done: the front end ends with ``code`` after showing ``message`` (one line)."""

    message: str
    code: int


StationEvent = (FromLink | LinkUp | LinkDown | LinkWaiting | LinkConnecting | LinkFailed | StatsSample | Requested
                | NotSent | Note | StickSet | JoystickNamed | EventsCleared | Fatal)


