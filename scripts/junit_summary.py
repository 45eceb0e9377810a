"""Print "N passed, N failed" for the pytest JUnit XML reports written by scripts/run.sh.

Usage: python scripts/junit_summary.py REPORT_DIR NPROCS [all|serial|mpi]

REPORT_DIR holds serial.xml (the serial run) and mpi-rank<r>.xml for r < NPROCS (the mpirun run);
the third argument counts one of the two runs alone (scripts/run.sh test --part).
A test counts once per run; under mpirun it failed if it failed or errored on any rank. A report
that is missing (pytest crashed or was killed) counts as one more failure.
"""

import sys
import xml.etree.ElementTree as ET
from pathlib import Path

SEVERITY = {"skipped": 0, "passed": 1, "failed": 2}


def merged_outcomes(paths: list[Path]) -> dict[tuple[str, str], str]:
    """Map each test to its worst outcome over the reports of one run's ranks."""
    result: dict[tuple[str, str], str] = {}
    for path in paths:
        for case in ET.parse(path).getroot().iter("testcase"):
            key = (case.get("classname", ""), case.get("name", ""))
            tags = {child.tag for child in case}
            if tags & {"failure", "error"}:
                outcome = "failed"
            elif "skipped" in tags:
                outcome = "skipped"
            else:
                outcome = "passed"
            if SEVERITY[outcome] >= SEVERITY[result.get(key, "skipped")]:
                result[key] = outcome
    return result


def main() -> None:
    reports, nprocs = Path(sys.argv[1]), int(sys.argv[2])
    part = sys.argv[3] if len(sys.argv) > 3 else "all"
    runs = {"serial": [["serial.xml"]], "mpi": [[f"mpi-rank{r}.xml" for r in range(nprocs)]]}
    runs["all"] = runs["serial"] + runs["mpi"]
    if part not in runs:
        sys.exit(f"junit_summary: unknown part {part!r} (known: all, serial, mpi)")
    passed = failed = 0
    for run in runs[part]:
        paths = [reports / name for name in run if (reports / name).exists()]
        failed += len(run) - len(paths)
        outcomes = list(merged_outcomes(paths).values())
        passed += outcomes.count("passed")
        failed += outcomes.count("failed")
    print(f"{passed} passed, {failed} failed")


if __name__ == "__main__":
    main()
