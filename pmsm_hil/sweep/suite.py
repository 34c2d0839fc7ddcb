"""`pmsm-hil test`: profiles run and judged against their acceptance criteria, as a regression
suite: one run in this process, several on Dask (the sweep machinery); a pass/fail table with the
measured value beside each bound; JUnit XML for CI.

A profile without an `acceptance:` section is held to the default: the whole profile played, no
fault.
"""

from __future__ import annotations

import json
import re
import shutil
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from pmsm_hil.profiles import Profile, ProfileError
from pmsm_hil.profiles.current_step import CurrentStep, current_step

from .execute import execute_run
from .plan import Run, profile_run, run_key

__all__ = ["DEFAULT_ACCEPTANCE", "SuiteCase", "junit_error", "junit_xml", "plan_suite", "run_suite"]

DEFAULT_ACCEPTANCE = {"run": {"complete": True, "faults": "forbidden"}}
METRICS = ["speed_error", "ripple", "recovery", "faults", "completeness", "angle"]


@dataclass
class SuiteCase:
    profile: str  # the path given
    name: str = ""  # the profile's name
    run: Run | None = None
    default_criteria: bool = False
    warnings: list[str] = field(default_factory=list)  # the profile's (as `run` prints them)
    step: CurrentStep | None = None  # the MPCC's current step (a hint when speeds miss)
    status: str = ""  # ok | failed (the run could not be made) | interrupted (Ctrl-C)
    error: str = ""
    checks: list[dict[str, Any]] = field(default_factory=list)
    log_path: str = ""
    wall_s: float = 0.0

    @property
    def passed(self) -> bool:
        return self.status == "ok" and bool(self.checks) and all(c["passed"] for c in self.checks)

    def hints(self) -> list[str]:
        """The hints for this case's missed criteria (analysis.acceptance: commission_hint,
        ripple_hint)."""
        from pmsm_hil.analysis.acceptance import Check, hints

        if not self.run:
            return []
        return hints(
            [Check(**ch) for ch in self.checks],
            self.run.texts.get("motor.yaml", ""),
            self.run.texts.get("rig.yaml", ""),
            self.step,
        )


def plan_suite(
    profiles: list[str], seed: int = 1, rig: str | None = None, motor: str | None = None
) -> list[SuiteCase]:
    """One case per profile (validated here: raises ProfileError with the problems of every
    invalid profile). A name given twice gets its ordinal (`paper-a (2)`), so that the JUnit
    suites and the tables tell them apart."""
    cases = []
    problems = []
    seen: dict[str, int] = {}
    for i, p in enumerate(profiles):
        warnings: list[str] = []
        loaded: list[Profile] = []
        try:
            run = profile_run(
                p,
                index=i,
                seed=seed,
                rig_path=rig,
                motor_path=motor,
                warnings=warnings,
                loaded=loaded,
            )
        except ProfileError as e:
            problems += e.problems
            continue
        data = yaml.safe_load(run.texts["profile.yaml"])
        name = str(data.get("name", p))
        seen[name] = seen.get(name, 0) + 1
        if seen[name] > 1:
            name = f"{name} ({seen[name]})"
        case = SuiteCase(
            profile=p, name=name, run=run, warnings=warnings, step=current_step(loaded[0])
        )
        if not data.get("acceptance"):
            data["acceptance"] = DEFAULT_ACCEPTANCE
            run.texts["profile.yaml"] = yaml.safe_dump(data, sort_keys=False, width=1_000_000)
            run.key = run_key(run.texts, run.seed)
            case.default_criteria = True
        cases.append(case)
    if problems:
        raise ProfileError(problems)
    return cases


def run_suite(
    cases: list[SuiteCase],
    out: Path,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    keep_logs: bool = True,
    progress: bool = False,
) -> list[SuiteCase]:
    """Run every case into ``out`` (fresh: no resume; a firmware change is what is being tested)."""
    from .driver import result_row, run_runs, write_inputs
    from .results import Journal, write_table

    out = Path(out)
    for stale in ("results.jsonl", "results.parquet", "results.csv"):
        (out / stale).unlink(missing_ok=True)
    if (out / "logs").is_dir():
        shutil.rmtree(out / "logs")
    out.mkdir(parents=True, exist_ok=True)
    runs = [c.run for c in cases if c.run is not None]
    if len(runs) == 1 and scheduler is None:
        write_inputs(out, runs[0])
        log = str((out / "logs" / f"{runs[0].key}.mcap").resolve()) if keep_logs else None
        rows = [execute_run(runs[0].task(METRICS, log))]
        if keep_logs:  # the results table that --out keeps, as the runs on Dask leave it
            row = result_row(rows[0], runs[0])
            Journal(out).add(row)
            write_table(out, [row], [])
    else:
        res = run_runs(
            runs,
            out,
            METRICS,
            keep_logs=keep_logs,
            scheduler=scheduler,
            workers=workers,
            progress=progress,
            label="test",
        )
        rows = res.rows
        if res.interrupted:  # the runs that had not ended: interrupted, not failed
            ended = {r["key"] for r in rows}
            rows += [{"key": r.key, "interrupted": True} for r in runs if r.key not in ended]
    by_key = {r["key"]: r for r in rows}
    for c in cases:
        assert c.run is not None  # cases are made with their run (make_cases)
        row = by_key.get(c.run.key, {"status": "failed", "error": "no result"})
        c.status, c.error = row.get("status", "failed"), row.get("error", "")
        c.log_path, c.wall_s = row.get("log_path", ""), float(row.get("wall_s", 0.0) or 0.0)
        c.checks = json.loads(row["acceptance_checks"]) if row.get("acceptance_checks") else []
        if row.get("interrupted"):  # judged on a run stopped short, every check would mislead
            c.status, c.checks = "interrupted", []
            c.error = "interrupted (Ctrl-C, SIGTERM or SIGHUP): the run was stopped before its end"
    return cases


def junit_xml(cases: list[SuiteCase]) -> str:
    """JUnit XML: a test suite per profile (its properties: profile file, rig, motor, seed, the
    kept log), a test case per check (a failed run: one error case); totals on the root. The
    run's wall time is the suite's and its first case's (the checks after it take no time of
    note): the cases add up to the suite, as GitLab adds them, which shows a sum of zeros
    as a profile that took no time."""
    root = ET.Element("testsuites", name="pmsm-hil test")
    totals = {"tests": 0, "failures": 0, "errors": 0}
    for c in cases:
        suite = ET.SubElement(root, "testsuite", name=c.name, file=c.profile)
        props = ET.SubElement(suite, "properties")
        for name, value in _properties(c):
            ET.SubElement(props, "property", name=name, value=value)
        n = fails = errors = 0
        wall = f"{c.wall_s:.3f}"
        if c.status != "ok":
            tc = ET.SubElement(suite, "testcase", classname=_classname(c), name="run", time=wall)
            wall = "0"
            kind = "interrupted" if c.status == "interrupted" else "run"
            ET.SubElement(
                tc, "error", message=c.error or "the run failed", type=kind
            ).text = c.error
            n, errors = 1, 1
        for ch in c.checks:
            n += 1
            tc = ET.SubElement(
                suite,
                "testcase",
                classname=_classname(c),
                name=f"{ch['scope']}: {ch['criterion']}",
                time=wall,
            )
            wall = "0"
            text = f"measured {ch['measured']}, bound {ch['bound']}"
            ET.SubElement(tc, "system-out").text = text
            if not ch["passed"]:
                fails += 1
                ET.SubElement(
                    tc, "failure", message=text, type="acceptance"
                ).text = f"{c.name}, {ch['scope']}: {ch['criterion']} {text}"
        hints = c.hints()
        if hints:
            ET.SubElement(suite, "system-out").text = "\n".join(f"hint: {h}" for h in hints)
        for k, v in (("tests", n), ("failures", fails), ("errors", errors)):
            suite.set(k, str(v))
            totals[k] += v
        suite.set("time", f"{c.wall_s:.3f}")
    for k, v in totals.items():
        root.set(k, str(v))
    root.set("time", f"{sum(c.wall_s for c in cases):.3f}")
    return _serialised(root)


def _classname(c: SuiteCase) -> str:
    """The profile's name as a JUnit classname: Jenkins and GitLab read a dot as a package
    separator (`paper-a.v2` would show as class `v2` in package `paper-a`)."""
    return c.name.replace(".", "_")


def _properties(c: SuiteCase) -> list[tuple[str, str]]:
    out = [("profile", c.profile)]
    if c.run is not None:
        for f in ("rig", "motor"):
            data = yaml.safe_load(c.run.texts.get(f"{f}.yaml", "") or "") or {}
            out.append((f, str(data.get("name", ""))))
        out.append(("seed", str(c.run.seed)))
    if c.log_path:
        out.append(("log", c.log_path))
    return out


def junit_error(what: str, message: str) -> str:
    """JUnit XML for a suite that could not run (invalid inputs, no scheduler): one test case
    ``what`` in error with ``message``, so that CI shows why instead of finding no report."""
    root = ET.Element("testsuites", name="pmsm-hil test", tests="1", failures="0", errors="1")
    suite = ET.SubElement(root, "testsuite", name="pmsm-hil test", tests="1", failures="0")
    suite.set("errors", "1")
    tc = ET.SubElement(suite, "testcase", classname="pmsm-hil test", name=what)
    ET.SubElement(tc, "error", message=message.splitlines()[0] if message else what).text = message
    return _serialised(root)


# what XML 1.0 cannot hold at all, not even escaped (ElementTree writes it as it is: the file is
# then not XML, and CI finds no report): a control character in a profile's name, say
_NOT_XML = re.compile(r"[\x00-\x08\x0b\x0c\x0e-\x1f\ud800-\udfff\ufffe\uffff]")


def _xml_text(text: str) -> str:
    return _NOT_XML.sub(lambda m: f"\\x{ord(m.group()):02x}", text)


def _serialised(root: ET.Element) -> str:
    """The report as XML text: characters XML cannot hold are written as ``\\xNN``."""
    for el in root.iter():
        el.text = _xml_text(el.text) if el.text else el.text
        for k, v in list(el.attrib.items()):
            el.set(k, _xml_text(v))
    ET.indent(root)
    return ET.tostring(root, encoding="unicode", xml_declaration=True) + "\n"
