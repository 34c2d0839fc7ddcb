"""Generate pmsm_hil/live/foxglove-layout.json, the Foxglove layout for `pmsm-hil run --foxglove` and for
logs opened in Foxglove, with foxglove-sdk's layout types.

    python3 -m tools.gen_foxglove_layout           rewrite pmsm_hil/live/foxglove-layout.json
    python3 -m tools.gen_foxglove_layout --check   exit 1 if the file in the tree is stale

Panels: speed (reference, measured, estimated), i_d / i_q with their references, the four
parameters of every estimator against the plant's truth, and the angle / speed estimation error
(a user script: the firmware's angle minus the encoder's, wrapped to ±π).
The fields named here are checked against the log contract in tests/test_foxglove_live.py.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import foxglove.layouts as fl

ROOT = Path(__file__).resolve().parent.parent
OUT = "pmsm_hil/live/foxglove-layout.json"  # package data: installed beside the code
ESTIMATORS = ("rls", "adaline", "nlms_adaline")
WINDOW_S = 10.0

ERROR_SCRIPT = """\
// Estimation error: the angle and speed the firmware uses minus the encoder's (pmsm-hil).
import { Input } from "./types.ts";

type Output = { t_s: number; theta_err_rad: number; speed_err_rpm: number };

export const inputs = ["/pmsm/telemetry"];
export const output = "/foxglove_script/estimation_error";

export default function script(event: Input<"/pmsm/telemetry">): Output {
  const m = event.message;
  const d = m.theta_e_est_rad - m.theta_e_rad;
  const wrapped = ((((d + Math.PI) % (2 * Math.PI)) + 2 * Math.PI) % (2 * Math.PI)) - Math.PI;
  return { t_s: m.t_s, theta_err_rad: wrapped, speed_err_rpm: m.speed_est_rpm - m.speed_rpm };
}
"""


def _plot(title: str, y_label: str, series: list[tuple[str, str, str | None]]) -> fl.PlotPanel:
    paths = [
        fl.PlotSeries(value=v, label=label, line_style=style, timestamp_method="receiveTime")
        for v, label, style in series
    ]
    return fl.PlotPanel(
        title=title,
        config=fl.PlotConfig(
            paths=paths,
            y_axis_label=y_label,
            x_axis_label="time",
            show_legend=True,
            legend_display="top",
            is_synced=True,
            time_window_mode="sliding",
            following_view_width=WINDOW_S,
        ),
    )


def _param(field: str, name: str, unit: str) -> fl.PlotPanel:
    series = [
        (f"/sim/truth.{field}", "truth", "dashed"),
        (f'/pmsm/params{{estimator=="nominal"}}.{field}', "nominal", "dotted"),
    ]
    series += [(f'/pmsm/params{{estimator=="{e}"}}.{field}', e, None) for e in ESTIMATORS]
    return _plot(f"{name} vs truth", f"{name} ({unit})", series)


def layout() -> fl.Layout:
    speed = _plot(
        "speed",
        "speed (r/min)",
        [
            ("/pmsm/telemetry.speed_ref_rpm", "reference", "dashed"),
            ("/pmsm/telemetry.speed_rpm", "measured (encoder)", None),
            ("/pmsm/telemetry.speed_est_rpm", "estimated (firmware)", None),
        ],
    )
    i_d = _plot(
        "i_d",
        "i_d (A)",
        [
            ("/pmsm/telemetry.i_d_ref_a", "i_d reference", "dashed"),
            ("/pmsm/telemetry.i_d_a", "i_d measured", None),
        ],
    )
    i_q = _plot(
        "i_q",
        "i_q (A)",
        [
            ("/pmsm/telemetry.i_q_ref_a", "i_q reference", "dashed"),
            ("/pmsm/telemetry.i_q_a", "i_q measured", None),
        ],
    )
    err = _plot(
        "angle error (estimate − encoder)",
        "angle error (rad)",
        [("/foxglove_script/estimation_error.theta_err_rad", "θe,est − θe", None)],
    )
    params = [
        _param("l_d_h", "L_d", "H"),
        _param("l_q_h", "L_q", "H"),
        _param("psi_f_wb", "ψ_f", "Wb"),
        _param("r_s_ohm", "R_s", "Ω"),
    ]

    def col(*panels):
        return fl.SplitContainer(
            direction="column", items=[fl.SplitItem(content=p) for p in panels]
        )

    signals = fl.SplitContainer(
        direction="row",
        items=[fl.SplitItem(content=col(speed, err)), fl.SplitItem(content=col(i_d, i_q))],
    )
    return fl.Layout(
        content=fl.TabContainer(
            tabs=[
                fl.TabItem(title="signals", content=signals),
                fl.TabItem(title="parameters", content=col(*params)),
            ]
        ),
        user_scripts={
            "estimation_error": fl.UserScript(name="estimation error", source_code=ERROR_SCRIPT)
        },
    )


def render() -> str:
    return json.dumps(json.loads(layout().to_json()), indent=2, ensure_ascii=False) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="exit 1 if the file in the tree is stale")
    args = ap.parse_args(argv)
    text = render()
    path = ROOT / OUT
    if args.check:
        if not path.is_file() or path.read_text(encoding="utf-8") != text:
            print(f"{OUT} is stale: run python3 -m tools.gen_foxglove_layout", file=sys.stderr)
            return 1
        return 0
    path.write_text(text, encoding="utf-8")
    print(f"wrote {OUT}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
