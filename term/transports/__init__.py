"""Byte pipes behind one interface (``base.Transport``): serial, loopback, BLE. They move bytes, nothing else."""

from term.transports.base import Transport, TransportClosed, TransportError

__all__ = ["Transport", "TransportClosed", "TransportError"]
