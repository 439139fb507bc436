"""The solver's passes on a Dask LocalCluster whose workers keep the chunks."""

from __future__ import annotations

import time
import warnings

import numpy as np
import pytest

from mcsweep.astrometry.solve import prior_diagonal
from mcsweep.solver import GlobalProblem, solve_global
from mcsweep.solver.tasks import absorption_task, back_task, direction_task, forward_task, residual_task, setup_task

distributed = pytest.importorskip("distributed")

KW = dict(rtol=1e-10, update_tol_uas=1e-3, max_iter=12)  # bit identity needs no convergence


@pytest.fixture(scope="module")
def client(dask_local_client):
    return dask_local_client


@pytest.fixture(scope="module")
def problem_and_h(weak_problem):
    P = weak_problem
    rng = np.random.default_rng(61)
    problem = GlobalProblem(P["obs"], prior_diagonal(1000.0, 10.0), P["ra"], P["dec"], block_stars=128)
    assert len(problem.blocks) > 8
    # measurements: any vector will do for bit identity (the solver does not know the truth)
    return problem, rng.normal(size=P["obs"].size)


def _scattered(client, problem, h, chunk_stars=256):
    """The problem's chunks of ``chunk_stars`` stars with their measurements, on the cluster:
    (block ranges, DaskChunks)."""
    from mcsweep.solver.dask_resident import DaskChunks

    ranges = problem.chunks(chunk_stars)
    return ranges, DaskChunks.scatter(client, [(problem.blocks[lo:hi], [h[b.rows] for b in problem.blocks[lo:hi]])
                                               for lo, hi in ranges])


def _same(a, b):
    assert np.array_equal(a.x, b.x) and np.array_equal(a.attitude, b.attitude)
    assert np.array_equal(a.residuals, b.residuals) and a.residual_rms == b.residual_rms
    assert len(a.history) == len(b.history)
    assert [(r.relative_residual, r.residual_rms, r.update_max_uas) for r in a.history] == \
        [(r.relative_residual, r.residual_rms, r.update_max_uas) for r in b.history]


def test_dask_resident_solution_is_bit_identical_to_in_process_and_forked(problem_and_h, client):
    problem, h = problem_and_h
    ref = solve_global(problem, h, **KW)
    forked = solve_global(problem, h, workers=2, chunk_stars=256, **KW)
    for c in (128, 512):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            _same(solve_global(problem, h, dask_client=client, chunk_stars=c, **KW), ref)
        # the chunks are scattered, not put into the task graph
        assert not [w for w in caught if "large graph" in str(w.message).lower()]
    _same(forked, ref)


def test_dask_passes_send_attitude_vectors_only(problem_and_h, client):
    # After the chunks are on the workers, the star vectors stay there too: an
    # iteration sends the attitude vector once to every worker (a small one, as here, with
    # every task), plus a few numbers per chunk, and gets back two attitude-sized sums per
    # aligned run of a worker's chunks (DaskChunks.reduced: at most one per bit of the number
    # of chunks, per worker), whatever the number of stars.
    from mcsweep.solver.dask_resident import DaskChunks

    problem, h = problem_and_h
    ranges = problem.chunks(128)  # one block per chunk: many chunks per worker
    chunks = [problem.blocks[lo:hi] for lo, hi in ranges]
    res = DaskChunks.scatter(client, [(bl, [h[b.rows] for b in bl]) for bl in chunks])
    sol = solve_global(problem, h, resident_chunks=res, chunk_stars=128, **KW)
    k = len(sol.history)
    att_vector = 8 * problem.n_att
    workers = len(client.nthreads())
    sent, received = res.bytes_per_call(forward_task, back_task, direction_task)
    assert sent / k <= max(workers, len(chunks)) * att_vector + 1024 * len(chunks)
    assert len(chunks) >= 6 * workers
    _same(sol, solve_global(problem, h, **KW))
    assert received / k <= 2 * workers * len(chunks).bit_length() * (att_vector + 1024) < 2 * len(chunks) * att_vector
    assert sent / k < 5 * 8 * problem.n_stars  # less than one star vector
    # setup (its sums, then the Schur absorption: one slab at this size), then forward, back
    # and direction passes: one each before the first iteration, and after every iteration
    # but the last, which has its forward pass only; residuals
    assert res.passes == 4 + 3 * k


def test_live_workers_are_the_schedulers_during_its_identity_refreshes(client):
    # distributed's client refreshes its cached scheduler identity without the workers: a
    # refresh landing during Client.scheduler_info() returned no worker (CI, distributed
    # 2026.8: 58 of 1000 calls at a 5 ms refresh interval), and a chunk placed on workers[0]
    # failed. The live workers must be the scheduler's own, whenever they are asked.
    import dask

    from mcsweep.solver.dask_resident import live_workers

    expected = sorted(client.cluster.scheduler.workers)
    assert len(expected) == 2
    with dask.config.set({"distributed.client.scheduler-info-interval": "5ms"}):
        refreshing = distributed.Client(client.cluster)
    try:
        got = [live_workers(refreshing) for _ in range(1000)]
    finally:
        refreshing.close()
    assert all(g == expected for g in got)


def test_solution_survives_a_killed_worker(problem_and_h, client, kill_worker_at):
    problem, h = problem_and_h
    ref = solve_global(problem, h, **KW)
    log = kill_worker_at(3)

    ranges, res = _scattered(client, problem, h)
    sol = solve_global(problem, h, resident_chunks=res, chunk_stars=256, log=log, **KW)
    assert log.killed and res.repeated >= 1  # the loss was met, and the pass repeated
    _same(sol, ref)
    client.wait_for_workers(2, timeout=60)  # the nanny restarts it for the next test


def test_chunks_kept_for_another_prior_give_that_priors_solution(problem_and_h, client, kill_worker_at):
    # The measurements sent once, the per-star inverses of each prior sent with its solution
    # (DaskChunks.attached with problem.attach_inverses): the solution of the new prior, bit for bit.
    from mcsweep.solver.dask_resident import DaskChunks
    from mcsweep.solver.problem import attach_inverses

    problem, h = problem_and_h
    other = problem.with_prior(prior_diagonal(1.0, 10.0))
    ranges = problem.chunks(256)
    base = DaskChunks.scatter(client, [(problem.blocks[lo:hi], [h[b.rows] for b in problem.blocks[lo:hi]])
                                       for lo, hi in ranges])
    stars = [slice(problem.blocks[lo].first, problem.blocks[hi - 1].first + problem.blocks[hi - 1].n)
             for lo, hi in ranges]
    ref = solve_global(other, h, **KW)
    res = base.attached(attach_inverses, [other.src_inv[sl] for sl in stars])
    _same(solve_global(other, h, resident_chunks=res, chunk_stars=256, **KW), ref)
    # and with a worker killed mid-solve: chunks and inverses sent again
    client.wait_for_workers(2, timeout=60)
    log = kill_worker_at(3)

    res = base.attached(attach_inverses, [other.src_inv[sl] for sl in stars])
    _same(solve_global(other, h, resident_chunks=res, chunk_stars=256, log=log, **KW), ref)
    client.wait_for_workers(2, timeout=60)  # the nanny restarts it for the next test
    assert log.killed and res.repeated >= 1
    client.wait_for_workers(2, timeout=60)


def test_an_error_of_the_task_is_raised_at_once_not_repeated(problem_and_h, client):
    # A task that fails by itself (here the solver's setup task given too few arguments, a
    # function the workers can import) is an error to raise, not a lost worker to recover from.
    client.wait_for_workers(2, timeout=60)
    problem, h = problem_and_h
    ranges, res = _scattered(client, problem, h)
    with pytest.raises(ValueError, match="values to unpack"):
        list(res.run(setup_task, [(ci,) for ci in range(len(ranges))]))
    assert res.repeated == 0 and res.passes == 0


def test_bytes_per_iteration_pass_are_tallied_apart_from_the_one_off_passes(problem_and_h, client):
    # The per-iteration figure the primary experiment prints counts the iteration
    # passes only; together with the setup and residual passes it is every byte sent.
    client.wait_for_workers(2, timeout=60)
    problem, h = problem_and_h
    ranges, res = _scattered(client, problem, h)
    solve_global(problem, h, resident_chunks=res, chunk_stars=256, **KW)
    it = res.bytes_per_call(forward_task, back_task, direction_task)
    once = res.bytes_per_call(setup_task, absorption_task, residual_task)
    assert set(res.bytes_by_task) == {"setup_task", "absorption_task", "forward_task", "back_task",
                                      "direction_task", "residual_task"}
    assert it[0] + once[0] == res.bytes_sent and it[1] + once[1] == res.bytes_received
    assert it[0] > 0 and once[0] > 0


def test_tasks_of_a_chunk_still_being_made_are_pinned_to_its_one_worker(client):
    # A chunk made by a task (the primary's blocks built on the workers) may still be running
    # when the first pass is sent: its tasks must wait and go to the one worker that holds it,
    # not run unpinned elsewhere on a copy with a state of its own (seen at the paper's sizes).
    from mcsweep.solver.dask_resident import DaskChunks

    client.wait_for_workers(2, timeout=60)
    # (a function the workers can import: one of this module they could not unpickle)
    res = DaskChunks(client, [client.submit(time.sleep, 1.0, pure=False)])
    assert res.futures[0].status == "pending"
    home = res._home(0)
    assert home is not None and len(home) == 1
    assert home == sorted(client.who_has(res.futures[0])[res.futures[0].key])[:1]
