"""SolverOptions (defaults, keywords, the PETSc options database, validation) and Report."""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest
import ufl
from petsc4py import PETSc
from petsc_db import petsc_options

import dolfinx_feti as df
from dolfinx_feti import factor as factor_module
from dolfinx_feti.factor import available_factors, default_factor

MESHES = Path(__file__).resolve().parents[2] / "meshes"


@pytest.fixture
def scratch():
    """A fresh directory of this rank's own (pytest's tmp_path is not safe under mpirun)."""
    d = Path(tempfile.mkdtemp(prefix="feti-report-"))
    yield d
    shutil.rmtree(d, ignore_errors=True)


@pytest.fixture(scope="module")
def b1_problem():
    mesh = df.read_gmsh(MESHES / "membranes_8.msh")

    def f(x):
        return ufl.conditional(ufl.lt(x[0], 1.0),
                               ufl.conditional(ufl.ge(x[1], 0.75), -3.0, 0.0),
                               ufl.conditional(ufl.lt(x[1], 0.25), -1.0, 0.0))

    return df.ContactProblem(mesh, df.Poisson(source=f), dirichlet=[df.Dirichlet("dirichlet")],
                             contact=[df.NodeToNode("contact_left", "contact_right")])


@pytest.fixture(scope="module")
def b1_solution(b1_problem):
    return df.solve(b1_problem, rtol=1e-8)


# ------------------------------------------------------------------------------------------
# SolverOptions
# ------------------------------------------------------------------------------------------

DEFAULTS = {"rtol": 1e-6, "stop_test": "kkt", "eq_rtol": None, "max_it": 5000, "max_outer": 1000,
            "factor": default_factor(), "mprgp_gamma": 1.0, "mprgp_expansion": "fixed",
            "smalbe_rho": 1.1, "smalbe_M": 1.0, "smalbe_eta": None, "smalbe_beta": 2.0,
            "norm_rtol": 1e-4, "verbose": 0, "mprgp_alpha": "fixed",
            "mprgp_reuse": 80, "mprgp_deflate": True, "mprgp_project": True,
            "mprgp_carry": True,
            "preconditioner": "lumped",
            "qp": "auto", "penalty_rho": 1e3, "smalbe_acceleration": "auto",
            "preconditioner_scaling": "stiffness",
            "smalbe_depth": 3, "smalbe_rho_growth": None, "smalbe_rho_max": 100.0,
            "error_if_not_converged": False, "method": "auto",
            "dual_operator": "implicit"}


def test_defaults():
    opts = df.SolverOptions()
    assert opts.to_dict() == DEFAULTS
    assert {f.name for f in fields(df.SolverOptions)} == set(DEFAULTS)
    assert df.SolverOptions.create() == opts
    opts.validate()


def test_default_factor_is_the_measured_choice():
    """CHOLMOD where PETSc has it, else PETSc's own Cholesky (docs/solvers.md); MUMPS is in
    every PETSc that DOLFINx runs on, and PETSc's own Cholesky is built in."""
    assert {"petsc", "mumps"} <= set(available_factors())
    expect = "cholmod" if "cholmod" in available_factors() else "petsc"
    assert default_factor() == expect == df.SolverOptions().factor


@pytest.mark.parametrize("name", ["cholmod", "mumps", "petsc"])
def test_unavailable_factor_is_refused_by_name(name):
    """A package this PETSc lacks (CHOLMOD with DOLFINx 0.11's wheel) is an InputError that
    names it and the packages there are; an available one is accepted as it is."""
    if name in available_factors():
        assert df.SolverOptions.create(factor=name).factor == name
        return
    with pytest.raises(df.InputError, match=f"factor '{name}' is not available.*available: "):
        df.SolverOptions.create(factor=name)


def test_missing_cholmod_is_refused_and_not_the_default(monkeypatch):
    """A PETSc without CHOLMOD (as DOLFINx 0.11's wheel has), simulated on any stack."""
    monkeypatch.setattr(factor_module, "available_factors", lambda: ("petsc", "mumps"))
    assert factor_module.default_factor() == "petsc"
    with pytest.raises(df.InputError, match="factor 'cholmod' is not available in this PETSc "
                                            r"\(.*\); available: petsc, mumps"):
        df.SolverOptions.create(factor="cholmod")
    with pytest.raises(df.InputError, match="factor must be one of 'cholmod', 'mumps', "
                                            "'petsc', got 'superlu'"):
        df.SolverOptions.create(factor="superlu")


def test_keyword_override():
    opts = df.SolverOptions.create(rtol=1e-3, max_it=7, factor="petsc",
                                   mprgp_expansion="optimal", eq_rtol=1e-4)
    assert (opts.rtol, opts.max_it, opts.factor) == (1e-3, 7, "petsc")
    assert opts.mprgp_expansion == "optimal" and opts.eq_rtol == 1e-4
    assert opts.max_outer == DEFAULTS["max_outer"]
    # None means "not given": the default stays
    assert df.SolverOptions.create(rtol=None).rtol == DEFAULTS["rtol"]


def test_petsc_options_database():
    with petsc_options(feti_rtol=1e-3):
        assert df.SolverOptions.create().rtol == 1e-3
        # an explicit keyword wins over the command line
        assert df.SolverOptions.create(rtol=1e-5).rtol == 1e-5
    assert df.SolverOptions.create().rtol == DEFAULTS["rtol"]  # removed again
    with petsc_options(feti_max_it="17", feti_mprgp_expansion="projcg", feti_eq_rtol="1e-7",
                       feti_smalbe_M="3"):
        opts = df.SolverOptions.create()
        assert opts.max_it == 17 and isinstance(opts.max_it, int)
        assert opts.mprgp_expansion == "projcg"
        assert opts.eq_rtol == 1e-7 and opts.smalbe_M == 3.0
    # another prefix reads other options
    with petsc_options(my_rtol=0.5):
        assert df.SolverOptions.create(prefix="my_").rtol == 0.5
        assert df.SolverOptions.create().rtol == DEFAULTS["rtol"]


def test_petsc_options_are_validated():
    with petsc_options(feti_rtol=-1.0):
        with pytest.raises(df.InputError, match="rtol"):
            df.SolverOptions.create()
    with petsc_options(feti_factor="lu"):
        with pytest.raises(df.InputError, match="factor"):
            df.SolverOptions.create()


@pytest.mark.parametrize("name, value", [("feti_rtol", "abc"), ("feti_max_it", "2.5"),
                                         ("feti_error_if_not_converged", "maybe")])
def test_bad_petsc_option_value_is_input_error(name, value):
    with petsc_options(**{name: value}):
        with pytest.raises(df.InputError, match=name.removeprefix("feti_")):
            df.SolverOptions.create()


@pytest.mark.parametrize("kwargs, word", [
    ({"rtol": 0.0}, "rtol"), ({"rtol": -1e-8}, "rtol"), ({"rtol": math.nan}, "rtol"),
    ({"norm_rtol": 0.0}, "norm_rtol"), ({"mprgp_gamma": -1.0}, "mprgp_gamma"),
    ({"eq_rtol": 0.0}, "eq_rtol"), ({"max_it": 0}, "max_it"), ({"max_outer": 0}, "max_outer"),
    ({"factor": "lu"}, "factor"), ({"mprgp_expansion": "wide"}, "mprgp_expansion"),
    ({"smalbe_beta": 1.0}, "smalbe_beta"),
])
def test_validation_errors(kwargs, word):
    with pytest.raises(df.InputError, match=word):
        df.SolverOptions.create(**kwargs)
    with pytest.raises(df.InputError, match=word):
        df.SolverOptions(**kwargs).validate()


def test_unknown_option_lists_known():
    with pytest.raises(df.InputError) as info:
        df.SolverOptions.create(rtoll=1e-3)
    msg = str(info.value)
    assert "rtoll" in msg and "'rtol'" in msg and "'max_it'" in msg


def test_solve_records_options(b1_solution):
    opts = b1_solution.report.extra["options"]
    assert opts == df.SolverOptions.create(rtol=1e-8).to_dict()
    assert opts["rtol"] == 1e-8


def test_solve_validates_explicit_options(b1_problem):
    with pytest.raises(df.InputError, match="rtol"):
        df.solve(b1_problem, options=df.SolverOptions(rtol=-1.0))


def test_solve_options_and_keywords_not_silently_ignored(b1_problem):
    try:
        sol = df.solve(b1_problem, options=df.SolverOptions(), rtol=1e-3)
    except df.InputError as e:  # refusing the combination is fine too
        assert "rtol" in str(e)
        return
    assert sol.report.extra["options"]["rtol"] == 1e-3


# ------------------------------------------------------------------------------------------
# Report
# ------------------------------------------------------------------------------------------


def _report(converged: bool) -> df.Report:
    return df.Report(solver="smalbe", converged=converged,
                     reason="converged" if converged else "max_it",
                     sizes={"primal": 10, "dual": 4, "inequality": 2, "subdomains": 2,
                            "ranks": 1},
                     outer_iterations=2, iterations=9, hessian_mults=11, hessian_mults_total=20,
                     gP_rel=1e-9, G_lambda=2e-10, kkt={"equilibrium": 1e-12},
                     timings={"total": 0.5},
                     warnings=[] if converged else ["the QP solver did not converge"])


def test_report_to_dict_is_json(b1_solution):
    rep = b1_solution.report
    d = rep.to_dict()
    assert {f.name for f in fields(df.Report)} == set(d)
    text = json.dumps(d, allow_nan=False)  # strict JSON: no NaN in a finished solve's report
    back = json.loads(text)
    assert back["converged"] is True and back["sizes"] == rep.sizes
    assert back["kkt"] == pytest.approx(rep.kkt)
    # a fresh Report (NaN placeholders) still serialises
    json.dumps(df.Report().to_dict())
    # to_dict is a copy: changing it leaves the report alone
    d["sizes"]["primal"] = -1
    assert rep.sizes["primal"] != -1


def test_save_json_writes_and_creates_dirs(scratch, b1_solution):
    path = scratch / "sub" / "dir" / "report.json"
    b1_solution.report.save_json(path)
    assert path.is_file()
    data = json.loads(path.read_text())
    assert data["converged"] is True
    assert data["sizes"] == b1_solution.report.sizes
    assert data["extra"]["options"]["rtol"] == 1e-8
    assert sorted(p.name for p in path.parent.iterdir()) == ["report.json"]  # no temporary left
    # numpy scalars are written as numbers
    rep = _report(True)
    rep.extra["np"] = np.float64(2.5)
    rep.extra["npi"] = np.int64(3)
    rep.save_json(scratch / "np.json")
    data = json.loads((scratch / "np.json").read_text())
    assert data["extra"] == {"np": 2.5, "npi": 3.0}


def test_save_json_failure_leaves_no_file(scratch):
    rep = _report(True)
    rep.extra["bad"] = object()  # cannot be written
    target = scratch / "report.json"
    with pytest.raises((TypeError, ValueError)):
        rep.save_json(target)
    assert list(scratch.iterdir()) == []
    # an existing report is not damaged by a failing rewrite
    _report(False).save_json(target)
    before = target.read_text()
    with pytest.raises((TypeError, ValueError)):
        rep.save_json(target)
    assert target.read_text() == before
    assert [p.name for p in scratch.iterdir()] == ["report.json"]


def test_save_json_overwrites(scratch):
    target = scratch / "r.json"
    _report(False).save_json(target)
    _report(True).save_json(target)
    assert json.loads(target.read_text())["converged"] is True
    assert os.listdir(scratch) == ["r.json"]


def test_summary_converged_and_not():
    good = _report(True).summary()
    assert "converged" in good and "NOT CONVERGED" not in good
    assert "2 subdomains" in good and "warning" not in good
    bad = _report(False).summary()
    assert "NOT CONVERGED" in bad and "max_it" in bad
    assert "warning: the QP solver did not converge" in bad
    # an empty report still prints
    assert "NOT CONVERGED" in df.Report().summary()


def test_summary_of_a_solve(b1_solution):
    rep = b1_solution.report
    text = rep.summary()
    # the default method: no gluing rows (one subdomain per membrane) → FETI-1; the left
    # membrane floats → SMALBE
    assert text.startswith("FETI-1 + smalbe: converged")
    assert f"{rep.sizes['primal']} primal dofs" in text
    assert f"{rep.sizes['ranks']} rank(s)" in text
    assert "F-multiplications" in text and "KKT" in text


def test_non_converged_solve_report(b1_problem):
    sol = df.solve(b1_problem, max_it=3)
    rep = sol.report
    assert rep.converged is False and rep.reason == "max_it"
    assert "NOT CONVERGED" in rep.summary()
    assert any("did not converge" in w for w in rep.warnings)
    assert all(math.isfinite(v) for v in (rep.gP_rel, rep.G_lambda, rep.norm_F))
    assert all(math.isfinite(v) for v in rep.kkt.values())
    json.dumps(rep.to_dict(), allow_nan=False)


def test_command_line_is_read_only_when_passed(monkeypatch):
    """-feti_* tokens are read from the argv the user passes (df.solve(options=sys.argv)),
    never from sys.argv behind the user's back, and nothing is written into PETSc's database."""
    import sys

    monkeypatch.setattr(sys, "argv", ["demo.py", "-feti_rtol", "1e-3"])
    assert df.SolverOptions.create().rtol == DEFAULTS["rtol"]
    o = df.SolverOptions.create(argv=["demo.py", "-feti_rtol", "1e-3", "--out", "x",
                                      "-feti_factor", "mumps", "-feti_verbose",
                                      "-feti_error_if_not_converged"])
    assert (o.rtol, o.factor, o.verbose, o.error_if_not_converged) == (1e-3, "mumps", 1, True)
    assert not any(PETSc.Options().hasName(n) for n in ("feti_rtol", "feti_factor",
                                                         "feti_verbose"))
    # precedence: database < argv < keywords
    with petsc_options(feti_rtol=1e-2, feti_max_it=7):
        o = df.SolverOptions.create(argv=["-feti_rtol", "1e-3"], rtol=None, max_outer=5)
        assert (o.rtol, o.max_it, o.max_outer) == (1e-3, 7, 5)
        assert df.SolverOptions.create(argv=["-feti_rtol", "1e-3"], rtol=1e-4).rtol == 1e-4
    with pytest.raises(df.InputError, match="did you mean 'rtol'"):
        df.SolverOptions.create(argv=["-feti_rtl", "1e-3"])
    with pytest.raises(df.InputError, match="solver option max_it must be an integer"):
        df.SolverOptions.create(argv=["-feti_max_it", "lots"])


def test_options_are_declared_next_to_each_solver():
    """Each solver's options come from its own declaration, under its nested prefix."""
    from dolfinx_feti.options import OPTION_SETS
    from dolfinx_feti.qp.mprgp import OPTIONS as MPRGP
    from dolfinx_feti.qp.smalbe import OPTIONS as SMALBE

    names = {f.name for f in fields(df.SolverOptions)}
    assert {f"smalbe_{k}" for k in SMALBE.options} <= names
    assert {f"mprgp_{k}" for k in MPRGP.options} <= names
    assert names == {s.key(k) for s in OPTION_SETS for k in s.options}
    o = df.SolverOptions.create(smalbe_rho=3.0, mprgp_expansion="optimal")
    assert o.of(SMALBE)["rho"] == 3.0 and o.of(MPRGP)["expansion"] == "optimal"
    for s in OPTION_SETS:
        for k, opt in s.options.items():
            assert getattr(df.SolverOptions(), s.key(k)) == opt.default
            assert s.key(k) in df.SolverOptions.__doc__


@pytest.mark.parametrize("max_it, code, label", [(3, -3, "max_it"), (5000, 5, "converged")])
def test_converged_reason(b1_problem, max_it, code, label):
    sol = df.solve(b1_problem, max_it=max_it, rtol=1e-8)
    rep = sol.report
    assert (rep.converged_reason, rep.reason, rep.converged) == (code, label, code > 0)
    assert f"reason {code:+d}" in rep.summary()
    from dolfinx_feti.qp import ConvergedReason

    assert ConvergedReason(code).label == label and ConvergedReason.of(label) == code


def test_error_if_not_converged(b1_problem):
    with pytest.raises(df.NotConverged, match="max_it") as info:
        df.solve(b1_problem, max_it=3, error_if_not_converged=True)
    assert info.value.solution.report.converged_reason == -3
    assert isinstance(info.value, df.SolveError)
    assert df.solve(b1_problem, rtol=1e-8, error_if_not_converged=True).report.converged


def test_every_solver_reason_has_a_signed_code():
    from dolfinx_feti.qp import ConvergedReason

    labels = {"rtol", "atol", "stop", "converged", "max_it", "max_outer", "unbounded",
              "breakdown", "non-finite iterate", "coulomb_max_steps"}
    assert {r.label for r in ConvergedReason} == labels
    assert all((r > 0) == r.name.startswith("CONVERGED") for r in ConvergedReason)
