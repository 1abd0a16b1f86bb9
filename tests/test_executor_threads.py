"""The runner's workers compute on one thread each (budget.runner.executors.worker_setup): numba's
and BLAS's; the caller's process, which works too, gets its own BLAS threads back afterwards."""

from __future__ import annotations

from threadpoolctl import threadpool_info

from budget.runner.executors import make_executor


def blas_threads() -> set[int]:
    """The thread counts of the BLAS libraries loaded in this process."""
    return {int(i["num_threads"]) for i in threadpool_info() if i["user_api"] == "blas"}


def test_one_blas_thread_in_every_worker_and_the_callers_given_back():
    before = blas_threads()
    assert before, "numpy's BLAS is loaded"
    with make_executor(workers=1) as ex:  # this process works alone
        assert blas_threads() == {1}
        assert [r for _, r in ex.map_unordered(_worker_blas, [0])] == [{1}]
    assert blas_threads() == before
    with make_executor(workers=2, work_here=True) as ex:  # a pool worker and this process
        got = [r for _, r in ex.map_unordered(_worker_blas, list(range(6)))]
        assert got == [{1}] * 6
    assert blas_threads() == before


def _worker_blas(_task) -> set[int]:
    return blas_threads()
