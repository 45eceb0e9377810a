"""Write docs/api.md: the public API of dolfinx_feti with the docstrings, from the code.

Usage: python scripts/gen_api_docs.py [--out docs/api.md] [--check]

Lists what ``dolfinx_feti.__all__`` exports and the public names of the modules below, each
with its signature and its docstring (Google-style sections become lists). ``--check`` exits
with status 1 when the file is not up to date, without writing it.
"""

from __future__ import annotations

import argparse
import importlib
import inspect
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: (module, names or None for the module's ``__all__``), in the order of the page.
SECTIONS = [
    ("dolfinx_feti", None),
    ("dolfinx_feti.io.problemfile", ["load", "ProblemFile", "ProblemFileError", "Fault",
                                  "OutputSpec", "PlotSpec", "FilePoisson", "SourceBox",
                                  "AffineTraction", "GridLabels", "generators",
                                  "check_command_line"]),
    ("dolfinx_feti.results.postprocess", None),
    ("dolfinx_feti.qp", ["QP", "QPSolver", "CG", "MPGP", "MPRGP", "SMALBE", "Absolute",
                         "QPResult", "ConvergedReason"]),
    ("dolfinx_feti.cli", ["main"]),
]
_SECTION = re.compile(r"^(Args|Arguments|Attributes|Returns|Raises|Yields|Note|Example|Examples):$")


def render_docstring(doc: str | None) -> str:
    """Markdown for a Google-style docstring: text as is, sections as bullet lists."""
    if not doc:
        return "*(no docstring)*\n"
    out, section, item = [], None, None

    def flush():
        nonlocal item
        if item is not None:
            out.append(item)
            item = None

    in_code = False
    for line in doc.splitlines():
        stripped = line.strip()
        if section is None and stripped.endswith("::"):
            out.append(line[:-1] if stripped != "::" else "")
            out.append("")
            out.append("```")
            in_code = True
            continue
        if in_code:
            if line and not line.startswith(" "):
                out.append("```")
                in_code = False
            else:
                if stripped or out[-1] != "```":
                    out.append(line[4:] if line.startswith("    ") else line)
                continue
        m = _SECTION.match(stripped)
        if m and not line.startswith(" "):
            flush()
            section = m.group(1)
            if out and out[-1] == "":
                out.pop()
            out.append(f"\n**{section}**\n")
            continue
        if section is not None:
            if not line.startswith(" ") and stripped:
                flush()
                section = None
                out.append(line)
                continue
            if not stripped:
                continue
            indent = len(line) - len(line.lstrip())
            if indent <= 4:
                flush()
                name, sep, rest = stripped.partition(":")
                if sep and section in ("Args", "Arguments", "Attributes", "Raises") and \
                        " " not in name.strip().replace(", ", ","):
                    item = f"- `{name.strip()}`:{rest}"
                else:
                    item = f"- {stripped}"
            else:
                item = (item or "-") + " " + stripped
            continue
        out.append(line)
    flush()
    if in_code:
        out.append("```")
    return "\n".join(out).strip() + "\n"


def _signature(obj) -> str:
    try:
        sig = str(inspect.signature(obj))
    except (TypeError, ValueError):
        return "(...)"
    sig = re.sub(r"<mpi4py\.MPI\.Intracomm object at 0x[0-9a-f]+>", "MPI.COMM_WORLD", sig)
    return sig.removesuffix(" -> None").removesuffix(" -> 'None'")


def _members(cls) -> dict:
    """A class's members, with those of its bases from this package, nearest first.

    Mixins such as the conditions' shared surface-pair part document their members here.
    """
    members: dict = {}
    for base in cls.__mro__:
        if base is cls or base.__module__.startswith("dolfinx_feti"):
            for name, member in vars(base).items():
                members.setdefault(name, member)
    return members


def describe(qualname: str, obj) -> list[str]:
    """Markdown for one public object."""
    lines = []
    if inspect.isclass(obj):
        lines.append(f"### class `{qualname}{_signature(obj)}`\n")
        lines.append(render_docstring(inspect.getdoc(obj)))
        for name, member in sorted(_members(obj).items()):
            if name.startswith("_") and name != "__call__":
                continue
            if isinstance(member, property):
                lines.append(f"#### property `{qualname}.{name}`\n")
                lines.append(render_docstring(inspect.getdoc(member)))
            elif isinstance(member, classmethod | staticmethod):
                fn = member.__func__
                lines.append(f"#### `{qualname}.{name}{_signature(fn)}`\n")
                lines.append(render_docstring(inspect.getdoc(fn)))
            elif inspect.isfunction(member):
                if not inspect.getdoc(member):
                    continue
                lines.append(f"#### `{qualname}.{name}{_signature(member)}`\n")
                lines.append(render_docstring(inspect.getdoc(member)))
    elif callable(obj):
        lines.append(f"### `{qualname}{_signature(obj)}`\n")
        lines.append(render_docstring(inspect.getdoc(obj)))
    else:
        lines.append(f"### `{qualname}`\n")
        lines.append(f"`{obj!r}`\n")
    return lines


def generate() -> str:
    """The whole page."""
    lines = ["# API reference", "",
             "Generated from the docstrings by `python scripts/gen_api_docs.py`; do not edit.",
             "The user guide is [index.md](index.md).", ""]
    for modname, names in SECTIONS:
        mod = importlib.import_module(modname)
        names = names if names is not None else list(getattr(mod, "__all__", []))
        lines.append(f"## `{modname}`\n")
        lines.append(render_docstring(inspect.getdoc(mod)))
        for name in names:
            if not hasattr(mod, name):
                continue
            lines += describe(f"{modname}.{name}", getattr(mod, name))
    return "\n".join(lines).rstrip() + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "api.md")
    parser.add_argument("--check", action="store_true", help="only check that it is current")
    args = parser.parse_args(argv)
    text = generate()
    if args.check:
        current = args.out.read_text() if args.out.exists() else ""
        if current != text:
            print(f"{args.out} is out of date: run python scripts/gen_api_docs.py")
            return 1
        return 0
    args.out.write_text(text)
    print(f"wrote {args.out} ({len(text.splitlines())} lines)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
