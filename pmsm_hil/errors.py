"""The errors that cross layers, in a module that depends on nothing: the transports raise
TransportError, the protocol raises DeviceError, the CLI maps both to exit codes."""

from __future__ import annotations


class TransportError(Exception):
    """The link cannot be opened or has dropped; the message says which port and why."""


class TransportSpecError(TransportError):
    """The user named a port or interface in a form that cannot be meant (bad input, exit 2)."""


class DeviceError(Exception):
    """The device refused, did not answer, or speaks another protocol; the message says which."""


__all__ = ["DeviceError", "TransportError", "TransportSpecError"]
