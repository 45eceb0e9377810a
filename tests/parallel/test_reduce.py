"""The buffer reductions of the inner loops agree with mpi4py's pickled ones on every rank."""

import numpy as np
from mpi4py import MPI

from dolfinx_feti.parallel.reduce import (
    any_rank,
    count,
    max_scalar,
    min_scalar,
    sum_array,
    sum_scalar,
)


def test_reductions_equal_the_pickled_ones():
    comm = MPI.COMM_WORLD
    r = comm.rank
    a = np.array([0.1 * (r + 1), -3.0 * r, 1e-300])
    s = sum_array(comm, a)
    assert s is not a and s.dtype == a.dtype
    assert np.array_equal(s, comm.allreduce(a, op=MPI.SUM))
    ints = np.array([r, 1, 0], dtype=np.int64)
    si = sum_array(comm, ints)
    assert si.dtype == np.int64 and np.array_equal(si, comm.allreduce(ints, op=MPI.SUM))
    block = np.arange(6.0).reshape(2, 3) * (r + 1)
    assert np.array_equal(sum_array(comm, block.T), comm.allreduce(block.T, op=MPI.SUM))
    x = 0.5 + r
    assert sum_scalar(comm, x) == comm.allreduce(x, op=MPI.SUM)
    assert max_scalar(comm, x) == comm.allreduce(x, op=MPI.MAX)
    assert min_scalar(comm, x) == comm.allreduce(x, op=MPI.MIN)
    assert count(comm, r + 2) == comm.allreduce(r + 2, op=MPI.SUM)
    assert any_rank(comm, r == comm.size - 1) is True
    assert any_rank(comm, False) is False
    assert isinstance(sum_scalar(comm, 1), float)
