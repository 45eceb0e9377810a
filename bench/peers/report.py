"""Tables and plots of the peer benchmarks from the JSON of ``bench/peers/run.py``.

Tables: markdown, printed and written to output/peers/tables.md (every row) and
output/peers/condensed.md (the tables of docs/peers.md). Plots: error against time per
problem, time against dofs.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parents[2] / "output" / "peers"
RAW = OUT / "raw"
FLOOR_ERR = 1e-15  # exact active-set results (error 0) are drawn here on the log scale
STYLE = {"FETI": "C0", "FETI tuned": "C9", "FETI lib default": "C5", "SNES-VI": "C1",
         "penalty": "C2", "Clarabel": "C3", "OSQP": "C4", "TFETI": "C6", "FETI-1": "C7",
         "FETI-DP": "C8", "FETI-DP tuned": "k"}
BY_METHOD = ("SNES-VI", "TFETI", "FETI-1", "FETI-DP", "FETI-DP tuned")
LEVEL_MARK = {"1": "o", "2": "s", "3": "^", "4": "D"}


def load() -> list[dict]:
    return [json.loads(p.read_text()) for p in sorted(RAW.glob("*.json"))]


def fmt(v, spec=".3g"):
    return "–" if v is None else format(v, spec)


def provenance(data: list[dict]) -> list[str]:
    """Per worker: the commit of the code and the machine line (load average at its end)."""
    out = ["\n### Provenance (one worker per problem × level × family)\n",
           "| worker | code (the tree's HEAD, or the export's commit) | dolfinx_feti from | "
           "machine at the end |", "|---|---|---|---|"]
    for d in sorted(data, key=lambda d: (d["problem"], d["level"], d["family"])):
        out.append(f"| {d['problem']} {d['level']} {d['family']} | {d.get('code', 'not recorded')}"
                   f" | {d.get('feti_module') or '–'} | {d['machine']} |")
    return out


def tables(data: list[dict]) -> str:
    out = provenance(data)
    for problem in ("sphere", "hertz", "b1"):
        ds = [d for d in data if d["problem"] == problem]
        if not ds:
            continue
        out.append(f"\n### {problem}: floors (same mesh, contact set fixed / glued)\n")
        out.append("| level | free dofs | contact rows | MUMPS Cholesky (s) | CG+GAMG (s) | "
                   "GAMG its |")
        out.append("|---|---|---|---|---|---|")
        seen = set()
        for d in sorted(ds, key=lambda d: d["level"]):
            if d["level"] in seen:
                continue
            seen.add(d["level"])
            lv = [e for e in ds if e["level"] == d["level"]]
            fm = min(e["floor"]["mumps"]["t"] for e in lv)
            fg = min(e["floor"]["gamg"]["t"] for e in lv)
            out.append(f"| {d['level']} | {d['ndofs']} | {d['ncontact']} | {fm:.3f} | {fg:.3f} | "
                       f"{d['floor']['gamg']['its']} |")
        out.append(f"\n### {problem}: contact solves\n")
        hertz = problem == "sphere"
        out.append("| level | dofs | method | tol / penalty | time (s) | ÷ MUMPS floor | "
                   "÷ GAMG floor | error (u, λ) vs exact | error F vs exact |"
                   + (" error F vs Hertz |" if hertz else "")
                   + " its (F-mults) | peak RSS (MiB) |")
        out.append("|---|---|---|---|---|---|---|---|---|" + ("---|" if hertz else "") + "---|---|")
        for d in sorted(ds, key=lambda d: (d["level"], d["family"])):
            for r in d["rows"]:
                its = r.get("its")
                if r["method"].startswith("FETI"):
                    its = f"{r['its']} ({r['mults']}), {r['parts']} parts"
                out.append(
                    f"| {d['level']} | {d['ndofs']} | {r['method']} | {r['param']:.0e} | "
                    f"{r['t']:.3f} | {r['ratio_mumps']:.1f} | {r['ratio_gamg']:.1f} | "
                    f"{r['err']:.1e} | {r['err_F']:.1e} |"
                    + (f" {r['err_F_hertz']:.2%} |" if hertz else "")
                    + f" {its} | {r['rss_peak_mib']:.0f} |")
    text = "\n".join(out)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "tables.md").write_text(text + "\n")
    return text


def _cell(r: dict, mults: bool = True) -> str:
    out = f"{r['t']:.2f} ({r['ratio_mumps']:.1f}×), {r['err']:.1e}"
    return out + (f", {r['mults']}" if mults and "mults" in r else "")


def _rows(data, problem, level, family):
    for d in data:
        if (d["problem"], d["level"], d["family"]) == (problem, level, family):
            return d, {r["param"]: r for r in d["rows"]}
    return None, {}


def condensed(data: list[dict]) -> str:
    """The condensed tables of docs/peers.md, from the same JSON as ``tables``.

    Time in s (÷ MUMPS floor of the same process), error, F-multiplications (FETI).
    """
    out = ["\n### sphere (docs/peers.md)\n",
           "| level | free dofs | floor MUMPS / GAMG (s), FETI's process | "
           "SNES-VI (s) (÷ its floor) | FETI 1e-6: s (÷ floor), error, F-mults | FETI 1e-8 | "
           "FETI 1e-10 | FETI tuned 1e-6 |"
           " FETI tuned 1e-8 | FETI tuned 1e-10 |", "|---|---|---|---|---|---|---|---|---|---|"]
    levels = sorted({d["level"] for d in data if d["problem"] == "sphere"})
    for lv in levels:
        df_, feti = _rows(data, "sphere", lv, "feti")
        _, tuned = _rows(data, "sphere", lv, "feti_tuned")
        _, snes = _rows(data, "sphere", lv, "snes")
        if df_ is None:
            continue
        fl = df_["floor"]
        sn = (f"{min(r['t'] for r in snes.values()):.2f}–{max(r['t'] for r in snes.values()):.2f}"
              f" ({min(r['ratio_mumps'] for r in snes.values()):.1f}–"
              f"{max(r['ratio_mumps'] for r in snes.values()):.1f}×)") if snes else "–"
        cells = [_cell(feti[t]) if t in feti else "–" for t in (1e-6, 1e-8, 1e-10)]
        cells += [_cell(tuned[t]) if t in tuned else "–" for t in (1e-6, 1e-8, 1e-10)]
        out.append(f"| {lv} | {df_['ndofs']} | {fl['mumps']['t']:.3f} / {fl['gamg']['t']:.3f} | "
                   f"{sn} | " + " | ".join(cells) + " |")
    for problem, fams in (("hertz", ("feti", "feti_tuned", "feti_libdefault", "clarabel", "osqp",
                                     "penalty")),
                          ("b1", ("feti", "feti_libdefault", "clarabel", "penalty"))):
        out += [f"\n### {problem} (docs/peers.md)\n",
                "| level | free dofs | method | param | time (s) | ÷ MUMPS floor (same process) |"
                " error (u, λ) | F-mults | parts |", "|---|---|---|---|---|---|---|---|---|"]
        for lv in sorted({d["level"] for d in data if d["problem"] == problem}):
            for fam in fams:
                d, rows = _rows(data, problem, lv, fam)
                if d is None:
                    continue
                for p, r in rows.items():
                    out.append(f"| {lv} | {d['ndofs']} | {r['method']} | {p:.0e} | {r['t']:.2f} | "
                               f"{r['ratio_mumps']:.1f} | {r['err']:.1e} | {r.get('mults', '–')} |"
                               f" {r.get('parts', '–')} |")
    out += by_method(data)
    text = "\n".join(out)
    (OUT / "condensed.md").write_text(text + "\n")
    return text


def by_method(data: list[dict]) -> list[str]:
    """Issue 15: each method of ``df.solve`` beside SNES-VI in one worker per case."""
    out = ["\n### By method (issue 15; docs/peers.md)\n",
           "| case | free dofs | floor MUMPS (s) | rtol | " + " | ".join(BY_METHOD) + " |",
           "|---|---|---|---|" + "---|" * len(BY_METHOD)]
    ds = [d for d in data if d["family"] == "by_method"]
    for d in sorted(ds, key=lambda d: (d["problem"] != "hertz", d["level"])):
        for tol in sorted({r["param"] for r in d["rows"]}, reverse=True):
            rows = {r["method"]: r for r in d["rows"] if r["param"] == tol}
            cells = [_cell(rows[m]) if m in rows else "–" for m in BY_METHOD]
            out.append(f"| {d['level']} | {d['ndofs']} | {d['floor']['mumps']['t']:.3f} | "
                       f"{tol:.0e} | " + " | ".join(cells) + " |")
    return out


def plots(data: list[dict]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    for problem in ("sphere", "hertz", "b1"):
        ds = [d for d in data if d["problem"] == problem]
        if not ds:
            continue
        fig, ax = plt.subplots(figsize=(7, 5))
        for d in sorted(ds, key=lambda d: d["level"]):
            series = {}
            for r in d["rows"]:
                series.setdefault(r["method"], []).append(r)
            for method, rs in series.items():
                t = [r["t"] for r in rs]
                e = [max(r["err"], FLOOR_ERR) for r in rs]
                ax.loglog(t, e, "-" + LEVEL_MARK[d["level"][-1]], color=STYLE[method],
                          label=f"{method} {d['level']} ({d['ndofs']} dofs)")
            fm = d["floor"]["mumps"]["t"]
            ax.axvline(fm, color="k", lw=0.5, ls=":")
        h, lab = ax.get_legend_handles_labels()
        uniq = dict(zip(lab, h, strict=True))
        ax.legend(uniq.values(), uniq.keys(), fontsize=6, ncol=2)
        ax.set_xlabel("wall time of the solve (s)")
        ax.set_ylabel("max rel. error of u and λ vs exact solution on the same mesh")
        ax.set_title(f"{problem}: error against time (dotted: MUMPS floor per mesh; "
                     f"{FLOOR_ERR:g} = exact)", fontsize=8)
        fig.tight_layout()
        fig.savefig(OUT / f"{problem}_error_time.png", dpi=120)
        plt.close(fig)

    fig, axes = plt.subplots(1, 3, figsize=(16, 4.5))
    for ax, problem in zip(axes, ("sphere", "hertz", "b1"), strict=True):
        ds = [d for d in data if d["problem"] == problem]
        by = {}
        floors = {}
        for d in ds:
            for r in d["rows"]:
                if r["err"] <= 1e-6 or r["method"] == "SNES-VI":
                    key = (r["method"], d["ndofs"])
                    by[key] = min(by.get(key, np.inf), r["t"])
            for how in ("mumps", "gamg"):
                k = (f"floor {how}", d["ndofs"])
                floors[k] = min(floors.get(k, np.inf), d["floor"][how]["t"])
        for src in (by, floors):
            methods = sorted({m for m, _ in src})
            for m in methods:
                pts = sorted((n, t) for (mm, n), t in src.items() if mm == m)
                style = "o-" if src is by else ("--" if "mumps" in m else ":")
                ax.loglog([p[0] for p in pts], [p[1] for p in pts], style,
                          color=STYLE.get(m, "k"), label=m)
        ax.set_xlabel("free dofs")
        ax.set_ylabel("time (s) to error <= 1e-6 (floor: one linear solve)")
        ax.set_title(problem)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(OUT / "time_dofs.png", dpi=120)
    plt.close(fig)


def main() -> None:
    data = load()
    print(tables(data))
    print(condensed(data))
    plots(data)
    print(f"plots: {OUT}/{{sphere,hertz,b1}}_error_time.png, {OUT}/time_dofs.png")


if __name__ == "__main__":
    main()
