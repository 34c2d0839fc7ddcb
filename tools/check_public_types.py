"""Every public function of the package has its parameters and its return typed (.ci/lint).

    python3 -m tools.check_public_types [PATH ...]     (default: pmsm_hil)

Public: the name has no leading underscore, nor does the class or module it is in; `__init__`
and the other special methods count as their class's. `self` and `cls` need no annotation, nor
does `__init__`'s return. Generated modules are skipped (they are typed by their generator).
Exit 1 with one line per finding, file:line: name: what is missing.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

GENERATED = {"generated.py", "can_generated.py"}


def _public(name: str) -> bool:
    return not name.startswith("_") or (name.startswith("__") and name.endswith("__"))


def _missing(fn: ast.FunctionDef | ast.AsyncFunctionDef, method: bool) -> list[str]:
    a = fn.args
    params = a.posonlyargs + a.args + a.kwonlyargs
    if method and params and params[0].arg in ("self", "cls"):
        params = params[1:]
    out = [f"parameter '{p.arg}'" for p in params if p.annotation is None]
    out += [f"parameter '*{v.arg}'" for v in (a.vararg, a.kwarg) if v and v.annotation is None]
    if fn.returns is None and fn.name != "__init__":
        out.append("return")
    return out


def check_file(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    found: list[str] = []

    def visit(body: list[ast.stmt], method: bool) -> None:
        for node in body:
            if isinstance(node, ast.ClassDef) and _public(node.name):
                visit(node.body, True)
            elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and _public(node.name):
                if node.name.startswith("__") and node.name != "__init__" and node.returns:
                    continue
                for what in _missing(node, method):
                    found.append(f"{path}:{node.lineno}: {node.name}: {what} not typed")

    visit(tree.body, False)
    return found


def main(argv: list[str] | None = None) -> int:
    roots = [Path(p) for p in (argv if argv else ["pmsm_hil"])]
    files = sorted(f for r in roots for f in ([r] if r.is_file() else r.rglob("*.py")))
    found = [
        line
        for f in files
        if f.name not in GENERATED and not any(p.startswith("_") for p in f.parts[1:-1])
        for line in check_file(f)
    ]
    print("\n".join(found) if found else f"public functions typed: {len(files)} files")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
