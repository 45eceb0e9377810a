"""A fresh empty working directory per test (this rank's own) with a hang watchdog."""

from __future__ import annotations

import faulthandler
import shutil
import tempfile
from pathlib import Path

import pytest

#: A test that has not finished after this long dumps its stack and ends the process.
HANG_SECONDS = 120


def scratch_cwd_fixture(prefix: str):
    """An autouse fixture: each test runs in a new temporary directory named ``prefix*``."""

    @pytest.fixture(autouse=True)
    def scratch_cwd(monkeypatch):
        d = Path(tempfile.mkdtemp(prefix=prefix))
        monkeypatch.chdir(d)
        faulthandler.dump_traceback_later(HANG_SECONDS, exit=True)
        try:
            yield d
        finally:
            faulthandler.cancel_dump_traceback_later()
            shutil.rmtree(d, ignore_errors=True)

    return scratch_cwd
