"""`pmsm-hil profiles`: the shipped profiles, motor, rig, flux-map and sweep files."""

from __future__ import annotations

import argparse


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "profiles",
        help="list the shipped profiles, motors, rigs, flux maps and sweeps",
        description="Lists the files shipped with pmsm-hil. Any command that takes a "
        "profile, --motor or --rig accepts these bare names; a file path "
        "always wins over a shipped name.",
    )
    p.add_argument("--paths", action="store_true", help="show where each file is installed")


def _first_line(path) -> str:
    """A file's description: the YAML `description:` field; for a motor file without one, its
    machine data (pole pairs, R, L_d, L_q, psi_f, and whether it names a flux map)."""
    import yaml

    try:
        with open(path, encoding="utf-8") as f:
            data = yaml.safe_load(f)
    except (OSError, yaml.YAMLError):
        return ""
    if not isinstance(data, dict):
        return ""
    if data.get("description"):
        return str(data["description"])
    if "pole_pairs" in data and "psi_f_wb" in data:
        return _motor_line(data)
    return ""


def _criteria(path) -> str:
    """What a profile's `acceptance:` section bounds, in a few words (`pmsm-hil test` judges a
    profile without one only on completing without a fault)."""
    import yaml

    try:
        with open(path, encoding="utf-8") as f:
            acc = (yaml.safe_load(f) or {}).get("acceptance")
    except (OSError, yaml.YAMLError, AttributeError):
        return ""
    if not isinstance(acc, dict):
        return "-"
    words = []
    run = acc.get("run")
    if not isinstance(run, dict):
        run = {}
    for key, v in run.items():
        if key == "identification" and isinstance(v, list):
            words.append(f"identification ({len(v)})")
        elif key not in ("complete", "faults"):
            words.append(
                key.removesuffix("_max_rpm").removesuffix("_max_s").removesuffix("_max_rad")
            )
    segs = acc.get("segments")
    if isinstance(segs, list) and segs:
        words.append(f"{len(segs)} segment{'s' if len(segs) > 1 else ''}")
    return ", ".join(words) or "complete, no fault"


def _motor_line(d: dict) -> str:
    def num(key: str, scale: float, unit: str) -> str:
        v = d.get(key)
        return f"{v * scale:g} {unit}" if isinstance(v, int | float) else "?"

    kind = "SPMSM" if d.get("l_d_h") == d.get("l_q_h") else "IPMSM"
    text = (
        f"{kind}, p = {d.get('pole_pairs')}, R {num('r_s_ohm', 1, 'ohm')}, "
        f"L_d {num('l_d_h', 1e3, 'mH')}, L_q {num('l_q_h', 1e3, 'mH')}, "
        f"psi_f {num('psi_f_wb', 1, 'Wb')}"
    )
    return text + (", with its flux map" if d.get("flux_map") else "")


def main(args: argparse.Namespace) -> int:
    from rich.console import Console
    from rich.table import Table

    from pmsm_hil.profiles.shipped import KINDS, shipped, shipped_root

    console = Console()
    if not console.is_terminal:
        # --paths: every path whole on its line, to be copied (a deep install cut them with '...')
        longest = max((len(p.stem) + len(str(p)) for k in KINDS for p in shipped(k)), default=0)
        console = Console(width=max(console.width, 120, longest + 8 if args.paths else 0))
    for kind in KINDS:
        files = shipped(kind)
        tab = Table(title=f"{kind}s", title_justify="left", header_style="bold", box=None)
        tab.add_column("name", no_wrap=True)
        # on a narrow terminal a path is folded onto the next lines, never cut
        tab.add_column("path", overflow="fold") if args.paths else tab.add_column("description")
        criteria = kind == "profile" and not args.paths
        if criteria:  # what `pmsm-hil test` judges it on
            tab.add_column("acceptance criteria")
        for p in files:
            row = [
                p.stem,
                str(p)
                if args.paths
                else (
                    _first_line(p) if p.suffix == ".yaml" else "flux map (psi_d, psi_q vs i_d, i_q)"
                ),
            ]
            tab.add_row(*row, *([_criteria(p)] if criteria else []))
        console.print(tab)
        console.print()
    console.print(
        f"shipped with pmsm-hil in {shipped_root()}; use a bare name, e.g. "
        f"`pmsm-hil run paper-a --rig lab-typical`"
    )
    from pmsm_hil.protocol import dbc_path

    console.print(
        f"CAN database for a CAN analyser (node 1, docs/can.md): {dbc_path()}", soft_wrap=True
    )
    return 0
