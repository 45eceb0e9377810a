"""Static figures of the package's structure, for docs/architecture.md.

Prints, for the tree given (default: the working tree; ``--rev REV`` reads a commit instead):
modules at the package root and their share of the lines, import cycles between modules,
private names imported from another module, ``isinstance`` dispatch on condition classes,
the lines of the set-up pipeline's modules, and the longest function.

Run: ``python scripts/code_figures.py`` and ``python scripts/code_figures.py --rev 9114216``.
"""

from __future__ import annotations

import argparse
import ast
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "dolfinx_feti"
CONDITIONS = {"Mortar", "NodeToNode", "RigidObstacle", "Tie", "Tresca", "Coulomb"}
#: The modules that decompose, number the points, build the rows and the corners and hand out
#: the shares (both ways of holding the mesh).
#: The set-up pipeline's modules (before issue 21's item 4: both ways of holding the mesh;
#: after it: the one pipeline, its input of a whole mesh, and the kernels both used).
SETUP = ("share.py", "share_distributed.py", "setup/share.py", "setup/share_distributed.py",
         "setup/whole_mesh.py",
         "mesh/decompose.py", "mesh/dofpoints.py", "mesh/distributed_decompose.py",
         "mesh/distributed_points.py", "fem/corners.py", "fem/distributed_corners.py",
         "constraints/build.py", "constraints/distributed_rows.py")


def sources(rev: str | None) -> dict[str, str]:
    """Package path (relative to the package) → source, of the working tree or of ``rev``."""
    if rev is None:
        return {str(p.relative_to(ROOT / PACKAGE)): p.read_text()
                for p in sorted((ROOT / PACKAGE).rglob("*.py"))}
    names = subprocess.run(["git", "ls-tree", "-r", "--name-only", rev, PACKAGE], cwd=ROOT,
                           capture_output=True, text=True, check=True).stdout.split()
    return {n[len(PACKAGE) + 1:]: subprocess.run(["git", "show", f"{rev}:{n}"], cwd=ROOT,
                                                 capture_output=True, text=True,
                                                 check=True).stdout
            for n in names if n.endswith(".py")}


def module_name(path: str) -> str:
    parts = path[:-3].split("/")
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join([PACKAGE, *parts])


def imports(path: str, tree: ast.AST, known: set[str]) -> list[tuple[str, list[str]]]:
    """(imported module, names) of every import inside the package."""
    here = module_name(path).split(".")
    package = here if path.endswith("__init__.py") else here[:-1]
    out = []
    typing_only = {id(n) for block in ast.walk(tree) if isinstance(block, ast.If)
                   and getattr(block.test, "id", None) == "TYPE_CHECKING"
                   for n in ast.walk(block)}
    for node in ast.walk(tree):
        if id(node) in typing_only:  # annotations only: not an import at run time
            continue
        if isinstance(node, ast.ImportFrom):
            base = package[:len(package) - node.level + 1] if node.level else []
            mod = ".".join(base + (node.module.split(".") if node.module else [])) \
                if node.level else (node.module or "")
            names = [a.name for a in node.names]
            for n in names:  # "from . import x" may import a module
                if f"{mod}.{n}" in known:
                    out.append((f"{mod}.{n}", []))
            if mod in known:
                out.append((mod, names))
        elif isinstance(node, ast.Import):
            out.extend((a.name, []) for a in node.names if a.name in known)
    return out


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v, counter=[0]):  # noqa: B006  (a counter shared by the recursion)
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def figures(src: dict[str, str]) -> dict:
    trees = {p: ast.parse(s) for p, s in src.items()}
    known = {module_name(p) for p in src}
    lines = {p: len(s.splitlines()) for p, s in src.items()}
    total = sum(lines.values())
    root = [p for p in src if "/" not in p and p != "__init__.py"]
    graph: dict[str, set[str]] = {}
    private = []
    dispatch = 0
    longest = (0, "")
    for p, tree in trees.items():
        me = module_name(p)
        for mod, names in imports(p, tree, known):
            if mod != me and not me.startswith(mod + "."):  # a package's own __init__
                graph.setdefault(me, set()).add(mod)
            private += [f"{me} ← {mod}.{n}" for n in names
                        if n.startswith("_") and not n.startswith("__") and mod != me]
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "isinstance" \
                    and len(node.args) == 2:
                kinds = node.args[1]
                names = {getattr(e, "id", getattr(e, "attr", None)) for e in
                         (kinds.elts if isinstance(kinds, ast.Tuple) else [kinds])}
                dispatch += bool(names & CONDITIONS)
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                longest = max(longest, (n, f"{me}.{node.name}"))
    return {"modules": len(src), "lines": total, "root_modules": len(root),
            "root_share": sum(lines[p] for p in root) / total,
            "import_cycles": cycles(graph), "private_imports": sorted(set(private)),
            "isinstance_dispatch": dispatch,
            "setup_lines": sum(lines.get(p, 0) for p in SETUP),
            "longest_function": longest}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rev", default=None, help="a commit to read instead of the working tree")
    ap.add_argument("--list", action="store_true", help="list the private imports")
    f = figures(sources(ap.parse_args().rev))
    args = ap.parse_args()
    print(f"modules {f['modules']}, lines {f['lines']}")
    print(f"root modules {f['root_modules']} ({100 * f['root_share']:.0f} % of the lines)")
    print(f"import cycles {len(f['import_cycles'])}: {f['import_cycles']}")
    print(f"private names imported across modules {len(f['private_imports'])}")
    if args.list:
        print("\n".join("  " + s for s in f["private_imports"]))
    print(f"isinstance dispatch on condition classes {f['isinstance_dispatch']}")
    print(f"set-up pipeline lines {f['setup_lines']}")
    print(f"longest function {f['longest_function'][0]} lines ({f['longest_function'][1]})")


if __name__ == "__main__":
    main()
