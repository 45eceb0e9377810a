"""Checks of a load path's output files (solve_path's xdmf and history)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path


def check_xdmf_series(folder: Path, steps: int) -> None:
    """path.xdmf holds, per step, u, the pressure, the tangential traction and the stick/slip
    state at the step's time; its HDF5 file is there and no temporary file is left."""
    text = (folder / "path.xdmf").read_text()
    assert text.count('<Time Value="') == 4 * steps
    names = [a.get("Name") for a in ET.fromstring(text).iter("Attribute")]
    for name in ("contact_pressure", "tangential_traction", "stick_slip"):
        assert names.count(name) == steps
    assert (folder / "path.h5").exists()
    assert not list(folder.glob(".tmp-*"))
