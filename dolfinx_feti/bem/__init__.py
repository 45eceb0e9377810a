"""Total BETI in 2D: boundary element subdomains on the FETI dual layer (Langer & Steinbach 2003).

Each subdomain's stiffness is its discrete Steklov–Poincaré operator on its boundary nodes
(:mod:`.steklov`), from Galerkin boundary integral operators (:mod:`.operators`) on its boundary
polygon (:mod:`.boundary`); :mod:`.tbeti` builds the dual QP of ``method="tbeti"``.
"""
