"""Byte pipes to a device (serial, pty, in process) and CAN buses (python-can)."""

from __future__ import annotations

import logging


def quiet_python_can() -> None:
    """python-can's socketcand client logs every partial TCP read as a warning ("Got incomplete
    message"): normal on a stream, noise on a terminal and by the thousand under a failed pytest
    test. Its real errors are raised, not logged. (python-can itself is not imported here.)"""
    logging.getLogger("can").setLevel(logging.ERROR)
