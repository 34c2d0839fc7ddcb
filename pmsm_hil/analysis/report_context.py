"""What every report panel needs from a log: its topics, the run's identity (profile, rig, seed)
for the titles, and the segment boundaries for the markers."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pmsm_hil.analysis.reading import recover_hint
from pmsm_hil.analysis.summary import rig_name
from pmsm_hil.log.reader import Log

# what the context reads of a log (read_log(path, topics=...)); the metadata come with any read
READS = {"/pmsm/events": ("t_s", "kind", "arg", "text")}


@dataclass
class Segment:
    index: int
    name: str
    t_start_s: float


@dataclass
class RunContext:
    log: Log
    path: Path
    profile: str
    rig: str
    seed: str
    board: str
    segments: list[Segment] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # things the reader of the report must know

    @property
    def tag(self) -> str:
        """The run's identity, for every title: profile, rig (or board) and seed."""
        seed = f"seed {self.seed}" if self.seed else "no seed (a rig)"
        where = f"rig {self.rig}" if self.rig else f"board {self.board or 'unknown'}"
        return f"{self.profile or self.path.stem} · {where} · {seed}"

    def has(self, topic: str) -> bool:
        return topic in self.log.topics and self.log.counts.get(topic, 0) > 0

    def topic(self, topic: str) -> dict[str, np.ndarray]:
        return self.log.topic(topic)


def run_context(log: Log, path: Path) -> RunContext:
    meta = log.metadata
    run = meta.get("run", {})
    ctx = RunContext(
        log=log,
        path=Path(path),
        profile=run.get("profile", ""),
        rig=rig_name(meta),
        seed=run.get("seed", ""),
        board=meta.get("device", {}).get("board", ""),
    )
    names = run.get("segment_names", "").split("|") if run.get("segment_names") else []
    stops = []
    if ctx.has("/pmsm/events"):
        ev = log.topic("/pmsm/events")
        for t, kind, arg, text in zip(ev["t_s"], ev["kind"], ev["arg"], ev["text"], strict=False):
            if str(kind) == "segment_start":
                i = int(arg)
                ctx.segments.append(
                    Segment(i, names[i] if 0 <= i < len(names) else f"segment {i}", float(t))
                )
            elif str(kind) == "stopped":
                stops.append(f"{float(t):.3f} s {text}")
    if not stops:
        ctx.notes.append(
            "The log has no `stopped` event: the run was cut off before the device "
            "reported its end."
        )
    elif not stops[-1].endswith("profile end"):
        ctx.notes.append(f"The run did not reach the profile's end: {stops[-1]}.")
    if names and ctx.segments and len({s.index for s in ctx.segments}) < len(names):
        seen = {s.index for s in ctx.segments}
        missing = [f"{i} {n}" for i, n in enumerate(names) if i not in seen]
        ctx.notes.append("Segments not reached: " + ", ".join(missing) + ".")
    if log.truncated or not log.finalised:
        ctx.notes.append(
            "The log is not finalised (the run was killed or the file is truncated): "
            f"the report shows what could be recovered{recover_hint(path)}."
        )
    for p in log.problems:
        ctx.notes.append(f"Log problem: {p}")
    return ctx
