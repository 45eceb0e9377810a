"""Drivers: one QP solve and the loops over one :class:`~dolfinx_feti.FetiSolver`.

:mod:`.qp_solve` runs the QP solver a dual QP needs and maps back (friction in
:mod:`.friction`); :mod:`.load_path` loops over load steps and load cases (their output
:mod:`.path_output`, proportional scaling :mod:`.scaled`). Nothing is imported here: the
solver object imports the QP solve, and the loops import the solver object.
"""
