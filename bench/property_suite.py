"""The property-based suite (tests/robustness/test_properties.py), many examples, a seed.

The normal test suite runs it with the "ci" profile (a few derandomized examples); this runs
the "bench" profile (``FETI_PROPERTIES=bench``: 40 examples per property, 400 per input
check) with a seed drawn now, or given, and printed first, so that a failure replays with
``--seed`` (Hypothesis also prints a ``@reproduce_failure`` blob of the failing example).

Run: ``python bench/property_suite.py [--seed N] [--examples K] [-k EXPR]`` (serially: ~1–3
minutes at the default size), or ``mpirun -n 2 python bench/property_suite.py --seed N`` (the
same seed on every rank: the same examples; adds the one-rank-against-all property).
"""

from __future__ import annotations

import argparse
import os
import random
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # this checkout's package, before any installed one


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seed", type=int, default=None, help="Hypothesis seed (default: a new one)")
    p.add_argument("--examples", type=int, default=None,
                   help="examples per property (default: the bench profile's 40)")
    p.add_argument("-k", default=None, help="pytest -k expression (a subset of the tests)")
    args = p.parse_args()
    from mpi4py import MPI

    comm = MPI.COMM_WORLD
    seed = args.seed if args.seed is not None else random.SystemRandom().randrange(2**32)
    seed = comm.bcast(seed, root=0)
    os.environ["FETI_PROPERTIES"] = "bench"
    if args.examples is not None:
        os.environ["FETI_PROPERTIES_EXAMPLES"] = str(args.examples)
    if comm.rank == 0:
        print(f"property suite: seed {seed} (replay: python bench/property_suite.py --seed "
              f"{seed}), {comm.size} rank(s)", flush=True)
    import pytest

    t0 = time.perf_counter()
    pytest_args = [str(ROOT / "tests" / "robustness" / "test_properties.py"), "-q",
                   "-p", "no:cacheprovider",
                   f"--hypothesis-seed={seed}", "--hypothesis-show-statistics"]
    if args.k:
        pytest_args += ["-k", args.k]
    os.chdir(ROOT)  # the project's pytest configuration
    status = pytest.main(pytest_args)
    if comm.rank == 0:
        print(f"property suite: seed {seed}, exit status {int(status)}, "
              f"{time.perf_counter() - t0:.0f} s", flush=True)
    return int(status)


if __name__ == "__main__":
    sys.exit(main())
