"""`pmsm-hil run --foxglove PORT`: the live streams over the Foxglove WebSocket protocol, decimated,
with JSON schemas that match the log; the layout file plots fields that exist."""

from __future__ import annotations

import asyncio
import itertools
import json
import os
import socket
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from pmsm_hil.live.foxglove import (
    LIVE_TOPICS,
    FoxgloveError,
    FoxgloveSink,
    json_schema,
    layout_path,
)
from pmsm_hil.live.ws_names import NameRelay, offered, rename
from pmsm_hil.log.reader import read_log
from pmsm_hil.log.schemas import TOPICS

websockets = pytest.importorskip("websockets")

# The Foxglove WebSocket protocol: foxglove-sdk >= 0.2x names it foxglove.sdk.v1 (the same protocol
# as foxglove.websocket.v1, renamed); a client offers both, as the Foxglove app does.
SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


async def _listen(port: int, seconds: float) -> tuple[dict, dict]:
    """Connect as Foxglove does, subscribe to every channel, collect messages for a while."""
    from websockets.asyncio.client import connect

    channels, got = {}, {}
    deadline = time.monotonic() + 30.0
    while True:
        try:
            ws = await connect(f"ws://127.0.0.1:{port}", subprotocols=SUBPROTOCOLS, open_timeout=2)
            break
        except OSError:
            if time.monotonic() > deadline:
                raise
            await asyncio.sleep(0.1)
    async with ws:
        assert ws.subprotocol in SUBPROTOCOLS
        end = time.monotonic() + seconds
        subscribed = False
        while time.monotonic() < end:
            try:
                raw = await asyncio.wait_for(ws.recv(), timeout=0.5)
            except TimeoutError:
                continue
            except websockets.exceptions.ConnectionClosed:  # the run ended
                break
            if isinstance(raw, str):
                m = json.loads(raw)
                if m.get("op") == "advertise":
                    for ch in m["channels"]:
                        channels[ch["id"]] = ch
                if channels and not subscribed:
                    await ws.send(
                        json.dumps(
                            {
                                "op": "subscribe",
                                "subscriptions": [
                                    {"id": cid, "channelId": cid} for cid in channels
                                ],
                            }
                        )
                    )
                    subscribed = True
            elif raw[0] == 0x01:  # message data: op, subscription id, log time, payload
                sub, log_time = struct.unpack_from("<IQ", raw, 1)
                topic = channels[sub]["topic"]
                got.setdefault(topic, []).append((log_time, json.loads(raw[13:])))
    return channels, got


def test_run_serves_the_live_streams_to_a_foxglove_client(root, tmp_path):
    port = free_port()
    out = tmp_path / "live.mcap"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "pmsm_hil.cli.main",
            "run",
            str(root / "tests" / "data" / "long.yaml"),
            "--no-live",
            "--foxglove",
            str(port),
            "--pace",  # paced, the device's heartbeat timeout (0.5 s) is 0.25 s of wall time
            "2",
            "--stop-after",
            "3",
            "--out",
            str(out),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        for line in proc.stdout:  # the address is printed before the run starts
            if line.startswith("foxglove:"):
                break
        assert line.strip() == f"foxglove: ws://127.0.0.1:{port} (layout: {layout_path()})"
        t0 = time.monotonic()
        channels, got = asyncio.run(_listen(port, 30.0))  # until the run ends
        print(
            f"listened {time.monotonic() - t0:.2f} s: "
            + ", ".join(f"{k} {len(v)}" for k, v in sorted(got.items()))
        )
    finally:
        _stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 0, stderr
    # every live topic is advertised with a JSON schema holding exactly the log's field names
    by_topic = {c["topic"]: c for c in channels.values()}
    assert set(by_topic) == set(LIVE_TOPICS)
    for topic, ch in by_topic.items():
        assert ch["encoding"] == "json" and ch["schemaEncoding"] == "jsonschema"
        assert ch["schemaName"] == TOPICS[topic].schema_name
        assert list(json.loads(ch["schema"])["properties"]) == list(TOPICS[topic].names)
    # messages arrive, with the log's field names, and their values are the logged ones
    assert len(got.get("/pmsm/telemetry", [])) > 50
    assert "/pmsm/status" in got and "/sim/truth" in got
    log = read_log(out)
    tel = log.topic("/pmsm/telemetry")
    sent = got["/pmsm/telemetry"]
    for _, msg in sent[:20]:
        assert set(msg) == set(TOPICS["/pmsm/telemetry"].names)
        i = round(msg["t_s"] * 2000)  # long.yaml streams telemetry at 2 kHz
        assert tel["t_s"][i] == pytest.approx(msg["t_s"])
        assert tel["speed_rpm"][i] == pytest.approx(msg["speed_rpm"], rel=1e-12)
    # decimated to <= 200 Hz of device time
    ts = [m["t_s"] for _, m in sent]
    assert min(b - a for a, b in itertools.pairwise(ts)) >= 1 / 200 - 1e-9
    # the log itself is complete: the sink decimates only what it sends
    assert len(tel["t_s"]) >= 3 * 2000 - 2


def test_sink_decimates_per_topic_and_never_raises(monkeypatch):
    sink = FoxgloveSink(0)
    try:
        for ch in sink._channels.values():
            monkeypatch.setattr(type(ch), "has_sinks", lambda self: True)
        for i in range(2000):  # one second of 2 kHz telemetry, offered as fast as possible
            sink.publish("/pmsm/telemetry", i / 2000, {"speed_rpm": 1.0, "i_d_a": float("nan")})
        # at most the wall-time burst: the host can offer frames far faster than real time
        assert 1 <= sink.published <= 25
        assert sink.published + sink.dropped == 2000
        sink.publish("/pmsm/unknown", 0.0, {})  # not a live topic: ignored
        sink.publish("/pmsm/params", 0.0, {})  # malformed: turns the sink off, no exception
        n = sink.published
        sink.publish("/pmsm/events", 9.0, {"kind": "host"})
        assert sink.published == n
    finally:
        sink.close()


async def _one_message(port: int, subprotocols: list[str], sink: FoxgloveSink) -> tuple:
    """Connect offering `subprotocols`, subscribe to /pmsm/status, have the sink publish one status
    message: (the name the server chose, the message's JSON)."""
    from websockets.asyncio.client import connect

    async with await connect(
        f"ws://127.0.0.1:{port}", subprotocols=subprotocols, open_timeout=5
    ) as ws:
        channels = {}
        while not channels:
            m = json.loads(await asyncio.wait_for(ws.recv(), timeout=5))
            if m.get("op") == "advertise":
                channels = {ch["topic"]: ch["id"] for ch in m["channels"]}
        cid = channels["/pmsm/status"]
        sub = {"op": "subscribe", "subscriptions": [{"id": 7, "channelId": cid}]}
        await ws.send(json.dumps(sub))
        deadline = time.monotonic() + 5
        while not sink._channels["/pmsm/status"].has_sinks():
            assert time.monotonic() < deadline, "the subscription never reached the server"
            await asyncio.sleep(0.02)
        sink.publish("/pmsm/status", 1.5, {"state": "run", "faults": 0})
        while True:
            raw = await asyncio.wait_for(ws.recv(), timeout=5)
            if isinstance(raw, bytes) and raw[0] == 0x01:
                assert struct.unpack_from("<I", raw, 1)[0] == 7
                return ws.subprotocol, json.loads(raw[13:])


@pytest.mark.parametrize("name", ["foxglove.websocket.v1", "foxglove.sdk.v1"])
def test_clients_that_know_either_name_of_the_protocol_connect(name):
    """PlotJuggler and older Lichtblick and Foxglove releases offer only foxglove.websocket.v1,
    which foxglove-sdk's own server refuses: the sink's port takes both names."""
    sink = FoxgloveSink(0)
    try:
        chosen, msg = asyncio.run(_one_message(sink.port, [name], sink))
        assert chosen == name
        assert msg == {"t_s": 1.5, "state": "run", "faults": 0}
        # behind the relay, the SDK's server itself answers only to its own name
        if name == "foxglove.websocket.v1":
            with pytest.raises(websockets.exceptions.InvalidStatus):
                asyncio.run(_one_message(sink._server.port, [name], sink))
    finally:
        sink.close()


def test_the_relay_renames_only_the_protocol_name():
    req = (
        b"GET / HTTP/1.1\r\nHost: x\r\nsec-WebSocket-Protocol: chat, foxglove.websocket.v1\r\n"
        b"Sec-WebSocket-Key: abc\r\n\r\n"
    )
    assert offered(req) == [b"chat", b"foxglove.websocket.v1"]
    out = rename(req, b"foxglove.websocket.v1", b"foxglove.sdk.v1")
    assert offered(out) == [b"chat", b"foxglove.sdk.v1"]
    assert out.replace(b"foxglove.sdk.v1", b"foxglove.websocket.v1") == req  # nothing else
    assert b"Sec-WebSocket-Key: abc\r\n\r\n" in out


def _answering_upstream() -> socket.socket:
    """A stand-in for the SDK's server: answers each handshake with 101 and closes."""
    srv = socket.create_server(("127.0.0.1", 0))

    def serve() -> None:
        while True:
            try:
                c, _ = srv.accept()
            except OSError:
                return
            with c:
                buf = b""
                while b"\r\n\r\n" not in buf:
                    chunk = c.recv(4096)
                    if not chunk:
                        break
                    buf += chunk
                c.sendall(b"HTTP/1.1 101 Switching Protocols\r\n\r\n")

    threading.Thread(target=serve, daemon=True).start()
    return srv


def _wait(cond, seconds: float = 5.0) -> bool:
    end = time.monotonic() + seconds
    while not cond():
        if time.monotonic() > end:
            return False
        time.sleep(0.01)
    return True


def test_the_relay_forgets_connections_that_ended_and_frees_its_port_when_closed():
    up = _answering_upstream()
    relay = NameRelay("127.0.0.1", 0, up.getsockname()[1])
    try:
        for _ in range(3):
            with socket.create_connection(("127.0.0.1", relay.port), timeout=5) as c:
                c.sendall(b"GET / HTTP/1.1\r\nHost: x\r\n\r\n")
                got = b""
                while chunk := c.recv(4096):  # the answer, then the upstream's close
                    got += chunk
                assert got.startswith(b"HTTP/1.1 101")
        assert _wait(lambda: not relay._conns), relay._conns  # none kept (each run adds some)
        # a client still in its handshake when the relay closes is let go at once
        pending = socket.create_connection(("127.0.0.1", relay.port), timeout=5)
        assert _wait(lambda: len(relay._conns) == 1)
    finally:
        relay.close()
        up.close()
    with pending:
        assert pending.recv(1) == b""  # not the 10 s handshake timeout
    # the port no longer listens: a second sink may take it
    socket.create_server(("127.0.0.1", relay.port)).close()


def test_sink_refuses_a_port_in_use_or_out_of_range():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        with pytest.raises(FoxgloveError, match=r"cannot listen on 127\.0\.0\.1"):
            FoxgloveSink(s.getsockname()[1])
    with pytest.raises(FoxgloveError, match="not a TCP port"):
        FoxgloveSink(70000)


def test_json_schemas_carry_units():
    s = json_schema("/pmsm/telemetry")
    assert s["properties"]["speed_rpm"]["type"] == "number"
    assert "[r/min]" in s["properties"]["speed_rpm"]["description"]
    assert json_schema("/pmsm/params")["properties"]["converged"]["type"] == "boolean"
    assert json_schema("/pmsm/status")["properties"]["segment"]["type"] == "integer"


def test_layout_plots_only_fields_that_are_streamed(root):
    layout = json.loads(Path(layout_path()).read_text())
    text = json.dumps(layout)
    import re

    paths = set(re.findall(r'"(/(?:pmsm|sim)/[a-z_]+)(?:\{[^}]*\})?\.([a-z_]+)', text))
    assert paths, "the layout plots nothing"
    for topic, fld in paths:
        assert topic in LIVE_TOPICS, topic
        assert fld in TOPICS[topic].names, (topic, fld)
    assert ('/pmsm/params{estimator==\\"nlms_adaline\\"}.psi_f_wb') in text
    for want in ("speed_ref_rpm", "speed_est_rpm", "i_d_ref_a", "i_q_ref_a", "l_d_h", "psi_f_wb"):
        assert want in text


def test_layout_file_is_generated(root):
    """The layout is the output of tools/gen_foxglove_layout.py, not edited by hand, and installed
    with the package (an installed pmsm-hil prints where)."""
    assert Path(layout_path()).is_file() and Path(layout_path()).parent.name == "live"
    r = subprocess.run(
        [sys.executable, "-m", "tools.gen_foxglove_layout", "--check"],
        cwd=root,
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr


def test_run_with_a_taken_port_is_bad_input(data, capsys, tmp_path):
    from pmsm_hil.cli.main import main

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        assert main(["run", str(data / "short.yaml"), "--no-live", "--foxglove", str(port)]) == 2
    err = capsys.readouterr().err
    assert f"--foxglove {port}: cannot listen on 127.0.0.1:{port}" in err and "Traceback" not in err
    assert main(["run", str(data / "short.yaml"), "--no-live", "--foxglove", "99999"]) == 2
    assert "--foxglove 99999: not a TCP port (0..65535" in capsys.readouterr().err
    for text in ("abc", "8765.5"):
        with pytest.raises(SystemExit) as ei:
            main(["run", str(data / "short.yaml"), "--no-live", "--foxglove", text])
        assert ei.value.code == 2
        assert f"--foxglove: '{text}' is not a TCP port (a whole number 0..65535" in (
            capsys.readouterr().err
        )
    # nothing was run: no empty log is left in runs/ (the working directory is tmp_path)
    assert list((tmp_path / "runs").glob("*.mcap")) == []


def test_on_the_emulator_the_stream_goes_in_real_time_unless_paced(data, tmp_path, monkeypatch):
    """A run streamed to Foxglove is there to be watched: on the emulator it goes at --pace 1
    unless --pace says otherwise (the device is not opened here: the pace it would get is seen)."""
    from pmsm_hil.cli import run as run_cli
    from pmsm_hil.cli.main import main
    from pmsm_hil.errors import TransportSpecError

    paces = []

    def device_spec(args):
        paces.append(args.pace)
        raise TransportSpecError("not opened in this test")

    monkeypatch.setattr(run_cli, "device_spec", device_spec)
    for extra in ([], ["--pace", "5"]):
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        args = ["run", str(data / "short.yaml"), "--no-live", "--out", str(tmp_path / "x.mcap")]
        assert main([*args, "--foxglove", str(port), *extra]) == 2
    assert main(args) == 2  # without --foxglove: as fast as it can
    assert paces == [1.0, 5.0, None]
