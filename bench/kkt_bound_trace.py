"""Trace the KKT stop's gradient bound (lengths and forces) through another bench script.

Runs a bench script (its arguments after ``--``) with :class:`.drivers.kkt_stop.KKTGradientTest`
and :class:`.drivers.kkt_stop.KKTStop` wrapped: every evaluation of the bound records its length
part, its force part, U and the tolerance; every Coulomb fixed point its steps (F-mults, change,
inner accuracy). Prints, for the first run of each solve's fixed point before the rescale of U
(in a cold solve the bonded step), where each part would have passed: the length part against
the U it had (``max_i |b_i| / scale_i``) and against the U the rescale took from its solution,
the force part ``max_i k_i |v_i| / R`` at η, 3η and 10η (history § 33.3). A variant of the
bound can be put in for the run:

- ``current``: the bound as it is;
- ``lengths-loosened``: no force part in a loosened run (``loosen > 1``);
- ``lengths-first``: no force part in the first loosened run of a solve (before the rescale);
- ``first-loosenN``: that first run loosened N times more.

Run (one process), e.g.::

    python bench/kkt_bound_trace.py --model-summary -- bench/coulomb_sliding.py \
        --models half,full --ratios 0.5 --max-it 30000
    python bench/kkt_bound_trace.py --variant lengths-first -- bench/load_path.py \
        --case coulomb2d --method auto
"""

from __future__ import annotations

import argparse
import json
import runpy
import sys
from pathlib import Path

import numpy as np

from dolfinx_feti.drivers import friction as fr
from dolfinx_feti.drivers import kkt_stop as ks

HERE = Path(__file__).resolve().parent


def _first_run(stop) -> bool:
    """Whether ``stop`` is before its first check and the rescale of U."""
    return stop.checks == 0 and not getattr(stop, "_rescaled", False)


def instrument(variant: str, log: list, steps: list) -> None:
    """Wrap the stop, its bound and the Coulomb fixed point to record into ``log``/``steps``."""
    make, call, rescale, run = (ks.KKTStop.make_test, ks.KKTGradientTest.__call__,
                                ks.KKTStop.rescale, fr.FrictionSolve.run)

    def make_test(self, loosen=1.0):
        saved = self.forces
        if (variant == "lengths-loosened" and loosen > 1) or \
                (variant == "lengths-first" and loosen > 1 and _first_run(self)):
            self.forces = None
        if variant.startswith("first-loosen") and loosen > 1 and _first_run(self):
            loosen *= float(variant[len("first-loosen"):])
        try:
            test = make(self, loosen)
        finally:
            self.forces = saved
        entry = {"new": True, "stop": id(self), "loosen": loosen, "U": self.U, "tol": test.tol,
                 "first": _first_run(self)}
        if self.forces is not None and not any(e.get("k") for e in log):
            fw, sc = self.forces[0], self.forces[1]
            k = fw[fw > 0] * sc[fw > 0]
            entry["k"] = [float(k.min()), float(np.median(k)), float(np.percentile(k, 90)),
                          float(k.max())] if k.size else None
        log.append(entry)
        return test

    def gradient_test(self, gP, x=None):
        ok = call(self, gP, x)
        g = np.abs(gP) * self.force_weight
        i = int(np.argmax(g)) if g.size else -1
        log.append({"length": self.length, "force": self.force, "U": self.U, "tol": self.tol,
                    "k": float(self.force_weight[i] * self.scale[i]) if i >= 0 else 0.0})
        return ok

    def take_scales(self, u, lam):
        self._rescaled = True
        return rescale(self, u, lam)

    def fixed_point(self, *args, **kwargs):
        n0 = len(self.info.get("steps", [])) if self.info else 0
        out = run(self, *args, **kwargs)
        steps.append([(s["hessian_mults"], s["change"], s["inner_rtol"])
                      for s in self.info.get("steps", [])[n0:]])
        return out

    ks.KKTStop.make_test, ks.KKTGradientTest.__call__ = make_test, gradient_test
    ks.KKTStop.rescale, fr.FrictionSolve.run = take_scales, fixed_point


def _first_at(values: list[float], limit: float) -> int | None:
    """The 1-based index of the first value <= limit (None: none)."""
    return next((j + 1 for j, v in enumerate(values) if v <= limit), None)


def first_steps(log: list) -> list[dict]:
    """Per first loosened run before the rescale: where each part passes (module docstring)."""
    runs: list[dict] = []
    for e in log:
        if e.get("new"):
            runs.append({"head": e, "calls": []})
        elif runs:
            runs[-1]["calls"].append(e)
    out = []
    for i, run in enumerate(runs[:-1]):
        head, calls, nxt = run["head"], run["calls"], runs[i + 1]["head"]
        if not head["first"] or head["loosen"] <= 1 or nxt["stop"] != head["stop"]:
            continue
        U0, U1 = head["U"], nxt["U"]
        eta = head["tol"] / U0
        length = [c["length"] for c in calls]
        force = [c["force"] / c["U"] for c in calls]  # max_i k_i |v_i| / R
        out.append({"U0": U0, "U_rescaled": U1, "ratio": U0 / U1, "eta": eta,
                    "tests": len(calls),
                    "length<=eta*U0": _first_at(length, eta * U0),
                    "length<=eta*U_rescaled": _first_at(length, eta * U1),
                    "force<=eta": _first_at(force, eta),
                    "force<=3eta": _first_at(force, 3 * eta),
                    "force<=10eta": _first_at(force, 10 * eta),
                    "k_binding_last": calls[-1]["k"] if calls else None})
    return out


def main() -> None:
    """Run the script after ``--`` instrumented; print the first runs' summary."""
    argv = sys.argv[1:]
    cut = argv.index("--") if "--" in argv else len(argv)
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--variant", default="current",
                    help="current | lengths-loosened | lengths-first | first-loosenN")
    ap.add_argument("--trace", type=Path, default=None, help="write the raw trace (json)")
    ap.add_argument("--model-summary", action="store_true",
                    help="print the k distribution of the contact rows")
    args = ap.parse_args(argv[:cut])
    script = argv[cut + 1:]
    if not script:
        ap.error("name the bench script after --")
    log: list = []
    steps: list = []
    instrument(args.variant, log, steps)
    sys.argv = script
    sys.path.insert(0, str(HERE))
    runpy.run_path(script[0], run_name="__main__")
    if args.model_summary:
        k = next((e["k"] for e in log if e.get("k")), None)
        print("k on the contact rows: min / median / p90 / max", k)
    print("first loosened run of each solve before the rescale (cold: the bonded step); "
          "bound evaluations at which each part passes:")
    for s in first_steps(log):
        print(json.dumps({key: round(v, 4) if isinstance(v, float) else v
                          for key, v in s.items()}))
    print("fixed points (F-mults, change, inner accuracy per step):")
    for fp in steps:
        print(" ", [(m, f"{c:.2g}", f"{e:.2g}") for m, c, e in fp])
    if args.trace is not None:
        args.trace.write_text(json.dumps({"log": log, "steps": steps}))


if __name__ == "__main__":
    main()
