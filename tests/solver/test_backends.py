"""The execution seam: a chunk holder is anything that implements ``executors.ChunkHolder``,
and the tasks reach their kernels through ``kernel_backend`` only. A third holder, written
here in one class (chunks held in this process, tasks on a thread pool), gives the solution
of the built-in ones bit for bit; kernels swapped through the switch point are the ones the
solver runs."""

from __future__ import annotations

import concurrent.futures
import contextlib
import types

import numpy as np
import pytest

from mcsweep.astrometry.solve import prior_diagonal
from mcsweep.solver import GlobalProblem, kernel_backend, kernels, solve_global
from mcsweep.solver.dask_resident import DaskChunks
from mcsweep.solver.executors import ChunkHolder, HeldChunks

KW = dict(rtol=1e-10, update_tol_uas=1e-3, max_iter=12)  # bit identity needs no convergence


class ThreadChunks:
    """Chunks ``(blocks, measurements, state)`` held here, their tasks run on a thread pool
    (results in completion order): a backend in one class."""

    shares = 1
    reduced = None

    def __init__(self, chunks, threads=3):
        self.chunks, self.threads = [tuple(c) for c in chunks], threads

    def run(self, fn, items):
        with concurrent.futures.ThreadPoolExecutor(self.threads) as pool:
            futures = [pool.submit(fn, (item[0], *self.chunks[item[0]], *item[1:])) for item in items]
            for f in concurrent.futures.as_completed(futures):
                yield f.result()

    def attached(self, fn, args):
        return ThreadChunks([fn(c, a) for c, a in zip(self.chunks, args)], self.threads)

    @contextlib.contextmanager
    def solving(self, keep=("x",)):
        yield self.run


@pytest.fixture(scope="module")
def problem_and_h(weak_problem):
    P = weak_problem
    problem = GlobalProblem(P["obs"], prior_diagonal(1000.0, 10.0), P["ra"], P["dec"], block_stars=128)
    return problem, np.random.default_rng(71).normal(size=P["obs"].size)


def _chunks(problem, h, chunk_stars=256):
    return [(problem.blocks[lo:hi], [h[b.rows] for b in problem.blocks[lo:hi]], {})
            for lo, hi in problem.chunks(chunk_stars)]


def _same(a, b):
    assert np.array_equal(a.x, b.x) and np.array_equal(a.attitude, b.attitude)
    assert np.array_equal(a.residuals, b.residuals) and a.residual_rms == b.residual_rms
    assert [(r.relative_residual, r.update_max_uas) for r in a.history] == \
        [(r.relative_residual, r.update_max_uas) for r in b.history]


def test_the_holders_declare_the_protocol():
    assert isinstance(ThreadChunks([]), ChunkHolder)
    assert isinstance(HeldChunks([]), ChunkHolder)
    assert isinstance(DaskChunks(None, []), ChunkHolder)
    assert not isinstance(object(), ChunkHolder)


def test_a_third_holder_in_one_class_gives_the_same_bits(problem_and_h):
    problem, h = problem_and_h
    ref = solve_global(problem, h, **KW)
    _same(solve_global(problem, h, resident_chunks=HeldChunks(_chunks(problem, h)), chunk_stars=256, **KW), ref)
    _same(solve_global(problem, h, resident_chunks=ThreadChunks(_chunks(problem, h)), chunk_stars=256, **KW), ref)


def test_kernels_swapped_at_the_switch_point_are_the_ones_run(problem_and_h):
    problem, h = problem_and_h
    ref = solve_global(problem, h, **KW)
    calls = dict.fromkeys(kernel_backend.KERNELS, 0)

    def counted(name):
        def call(*args, **kwargs):
            calls[name] += 1
            return getattr(kernels, name)(*args, **kwargs)
        return call

    counting = types.SimpleNamespace(**{name: counted(name) for name in kernel_backend.KERNELS})
    with kernel_backend.using(counting):
        assert kernel_backend.active() is counting
        sol = solve_global(problem, h, **KW)
    assert kernel_backend.active() is kernels
    _same(sol, ref)
    # every pass of every PCG iteration reaches its kernels through the switch point
    n_iter, n_blocks = len(sol.history), len(problem.blocks)
    assert calls["precondition_forward"] >= n_iter * n_blocks and calls["precondition_back"] >= n_iter * n_blocks
    assert calls["frame_sums"] > 0 and calls["frame_apply"] > 0 and calls["band_scatter"] > 0


def test_an_incomplete_kernel_set_is_refused_naming_what_it_lacks():
    with pytest.raises(TypeError, match="precondition_back"):
        with kernel_backend.using(types.SimpleNamespace(precondition_forward=kernels.precondition_forward)):
            pass
    assert kernel_backend.active() is kernels
