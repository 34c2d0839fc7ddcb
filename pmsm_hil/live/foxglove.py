"""Live streams over the Foxglove WebSocket protocol (foxglove-sdk), served on 127.0.0.1 while a run
is logged: `pmsm-hil run PROFILE --foxglove [PORT]` (docs/foxglove.md).

The recorder hands every decoded message to `FoxgloveSink.publish(topic, t_s, fields)` after
writing it to the log. The sink must never slow the link down, so it
- decimates: per topic (per estimator on /pmsm/params) at most RATE_HZ messages per second of
  device time *and* per second of wall time (a token bucket), whatever the emulator's pace;
- does the JSON encoding only when a client is subscribed to the channel;
- never blocks: foxglove-sdk queues each client's messages in its own thread and drops the oldest
  when a slow client falls behind;
- never raises into the recorder: an error turns the sink off with one warning.

Messages are JSON with the log's field names (t_s, then the fields of docs/log-format.md); the
channels' JSON schemas are generated from pmsm_hil.log.schemas, so they cannot drift from the log.
MCAP-style log time: the sink's start (wall clock, ns) + t_s.
"""

from __future__ import annotations

import contextlib
import json
import math
import sys
import time
from pathlib import Path

from pmsm_hil.live.ws_names import NameRelay
from pmsm_hil.log.schemas import TOPICS


def layout_path() -> str:
    """The Foxglove layout for these streams (installed with the package; written by
    tools/gen_foxglove_layout.py): Foxglove, Layouts, Import from file."""
    return str(Path(__file__).with_name("foxglove-layout.json"))


DEFAULT_PORT = 8765
HOST = "127.0.0.1"
LIVE_TOPICS = (
    "/pmsm/telemetry",
    "/pmsm/estimator",
    "/pmsm/params",
    "/pmsm/status",
    "/pmsm/events",
    "/sim/truth",
)
# messages per second per key (topic, or topic + estimator), in device time and in wall time
RATE_HZ = {
    "/pmsm/telemetry": 200.0,
    "/pmsm/estimator": 100.0,
    "/pmsm/params": 50.0,
    "/sim/truth": 100.0,
    "/pmsm/status": 20.0,
    "/pmsm/events": math.inf,
}
BURST = 20  # wall-time token bucket depth (messages)

_JSON_TYPES = {"string": "string", "bool": "boolean", "float32": "number", "float64": "number"}


class FoxgloveError(Exception):
    """The server could not be started (e.g. the port is taken)."""


def json_schema(topic: str) -> dict:
    """The JSON schema of a live topic: the log's fields, names, units and meaning."""
    td = TOPICS[topic]
    props = {}
    for f in td.fields:
        desc = "; ".join(x for x in (f"[{f.unit}]" if f.unit else "", f.doc) if x)
        props[f.name] = {"type": _JSON_TYPES.get(f.type, "integer"), "description": desc}
    return {
        "title": td.schema_name,
        "description": td.doc,
        "type": "object",
        "properties": props,
        "required": list(props),
    }


class _Gate:
    """Decimation of one key: device-time spacing and a wall-time token bucket."""

    __slots__ = ("next_t", "period_s", "rate", "tokens", "wall")

    def __init__(self, rate_hz: float):
        self.rate = rate_hz
        self.period_s = 0.0 if math.isinf(rate_hz) else 1.0 / rate_hz
        self.next_t = -math.inf
        self.tokens = float(BURST)
        self.wall = time.monotonic()

    def admit(self, t_s: float) -> bool:
        if math.isinf(self.rate):
            return True
        if t_s < self.next_t:
            return False
        now = time.monotonic()
        self.tokens = min(float(BURST), self.tokens + (now - self.wall) * self.rate)
        self.wall = now
        if self.tokens < 1.0:
            return False
        self.tokens -= 1.0
        self.next_t = t_s + self.period_s
        return True


def _plain(v):
    if isinstance(v, float):
        return v if math.isfinite(v) else None
    if hasattr(v, "item"):  # numpy scalars
        return _plain(v.item())
    return v


class FoxgloveSink:
    """A Foxglove WebSocket server on 127.0.0.1:port with one JSON channel per live topic."""

    def __init__(self, port: int = DEFAULT_PORT, name: str = "pmsm-hil", rates: dict | None = None):
        try:
            import foxglove
        except ImportError as e:  # a broken install: say what is missing
            raise FoxgloveError(f"--foxglove needs the foxglove-sdk package ({e})") from None
        if not 0 <= port <= 65535:
            raise FoxgloveError(f"--foxglove {port}: not a TCP port (0..65535; 0 picks a free one)")
        self._ctx = foxglove.Context()
        try:
            self._server = foxglove.start_server(name=name, host=HOST, port=0, context=self._ctx)
        except (RuntimeError, OSError) as e:
            raise FoxgloveError(f"--foxglove: the Foxglove server did not start ({e})") from None
        try:
            # the user's port is the relay's, which takes both names of the protocol
            # (pmsm_hil/live/ws_names.py); the SDK's server listens on a port of its own
            self._relay = NameRelay(HOST, port, self._server.port)
        except (OSError, OverflowError) as e:
            self._server.stop()
            raise FoxgloveError(
                f"--foxglove {port}: cannot listen on {HOST}:{port} ({e})"
            ) from None
        self.port = self._relay.port
        self.rates = dict(RATE_HZ, **(rates or {}))
        self._channels = {}
        for topic in LIVE_TOPICS:
            sch = json_schema(topic)
            self._channels[topic] = foxglove.Channel(
                topic,
                context=self._ctx,
                message_encoding="json",
                schema=foxglove.Schema(
                    name=TOPICS[topic].schema_name,
                    encoding="jsonschema",
                    data=json.dumps(sch).encode(),
                ),
            )
        self._gates: dict[str, _Gate] = {}
        self._t0_ns = time.time_ns()
        self.published = 0
        self.dropped = 0
        self._broken = False

    @property
    def url(self) -> str:
        return f"ws://{HOST}:{self.port}"

    def publish(self, topic: str, t_s: float, fields: dict) -> None:
        """Offer one message; it is sent if a client listens and the topic's rate allows."""
        if self._broken:
            return
        ch = self._channels.get(topic)
        if ch is None:
            return
        try:
            key = topic + "/" + fields["estimator"] if topic == "/pmsm/params" else topic
            gate = self._gates.get(key)
            if gate is None:
                gate = self._gates[key] = _Gate(self.rates.get(topic, 100.0))
            if not gate.admit(t_s):
                self.dropped += 1
                return
            if not ch.has_sinks():
                return
            msg = {"t_s": t_s}
            for k, v in fields.items():
                msg[k] = _plain(v)
            ch.log(
                json.dumps(msg, allow_nan=False).encode(), log_time=self._t0_ns + round(t_s * 1e9)
            )
            self.published += 1
        except Exception as e:  # the live view must never end a run
            self._broken = True
            print(f"warning: Foxglove live stream stopped: {e}", file=sys.stderr, flush=True)

    def close(self) -> None:
        for ch in self._channels.values():
            with contextlib.suppress(Exception):
                ch.close()
        self._server.stop()
        self._relay.close()
