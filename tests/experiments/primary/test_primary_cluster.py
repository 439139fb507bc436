"""The primary experiment's data built on the workers of a Dask cluster: the same bits
as the data built in the driver, and the same solution, while the driver never holds a
measurement."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pandas as pd
import pytest

from mcsweep.astrometry.design import JULIAN_YEAR_DAYS
from mcsweep.experiments.primary import experiment as P
from mcsweep.experiments.primary.local import prepare
from mcsweep.experiments.primary.prior_solution import solve_prior
from mcsweep.experiments.primary.transits import transits_of
from mcsweep.experiments.primary import results as primary_results

from .primary_cases import primary_config, synthetic_stars

distributed = pytest.importorskip("distributed")

BLOCK = 128  # stars per block: many blocks and chunks on a small problem, with fewer measurements
# than attitude unknowns each, so the solver sums them in leaves of several blocks (reduction)


@pytest.fixture(scope="module")
def client(dask_local_client):
    return dask_local_client


@pytest.fixture(scope="module")
def both(client):
    """(settings, data built in the driver, data built on the cluster) with noise, knots placed
    by the data and AL-only measurements off (AL + AC, the default)."""
    from mcsweep.experiments.primary.cluster import prepare_on_cluster
    from mcsweep.experiments.primary.sky import table_partitions

    config, _ = primary_config(["experiment.primary.knot_transits=25", "experiment.primary.solver_max_iter=15",
                         "experiment.primary.allow_unconverged=true"])
    settings = P.build_settings(config)
    stars = synthetic_stars(2500, 11)
    _, tr = transits_of((0, 0, stars["ra"].to_numpy(), stars["dec"].to_numpy(), settings.start_jd,
                           settings.end_jd, settings.law))
    local = prepare(settings, stars, tr, block_stars=BLOCK)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        # partitions of 700 stars: the blocks of solved stars run across them
        remote = prepare_on_cluster(settings, table_partitions(client, stars, 700), client, chunk_stars=2 * BLOCK,
                                    block_stars=BLOCK)
    assert not [w for w in caught if "large graph" in str(w.message).lower()]
    return settings, local, remote


def test_sky_partitions_are_the_driver_sort(client):
    # The classes put in sky order on the workers (primary_sky): the rows of the driver's sort
    # of the whole table (global_classes.sky_order), bit for bit, with stars sharing a pixel
    # within and across classes (the stable order decides their rows), in partitions that
    # cut the classes' pixel ranges; made again after a loss, the same frames.
    import functools

    from mcsweep.experiments.global_solution.classes import class_table, sky_order
    from mcsweep.experiments.primary.sky import sky_partitions

    frames = []
    for i, key in enumerate((1100, 1500, 1900)):
        df = synthetic_stars(3000, 20 + i).drop(columns="class_key")
        df.loc[:199, ["ra", "dec"]] = synthetic_stars(200, 99)[["ra", "dec"]].to_numpy()  # shared positions
        df.loc[200:299, ["ra", "dec"]] = df.loc[:99, ["ra", "dec"]].to_numpy()  # and within the class
        frames.append((key, df))
    whole = pd.concat([class_table(df, key) for key, df in frames], ignore_index=True)
    expected = whole.iloc[sky_order(whole["ra"].to_numpy(), whole["dec"].to_numpy())].reset_index(drop=True)
    # (tasks of functions the workers can import: a test module is not on their path when
    # pytest runs as a console script)
    sky, caught = sky_partitions(client, [(key, functools.partial(client.submit, pd.DataFrame.copy, df, pure=False))
                                          for key, df in frames], 700)
    assert caught == [] and len(sky) >= 10 and sky.n_stars == len(whole)
    got = client.gather(sky.futures)
    assert [len(g) for g in got] == sky.sizes.tolist()
    np.testing.assert_array_equal(sky.first, np.concatenate([[0], np.cumsum(sky.sizes)[:-1]]))
    pd.testing.assert_frame_equal(pd.concat(got, ignore_index=True), expected, check_exact=True)
    again = pd.concat(client.gather(sky.remake()), ignore_index=True)
    pd.testing.assert_frame_equal(again, expected, check_exact=True)


def test_knots_epochs_on_the_workers_answer_as_one_sorted_array(client, monkeypatch):
    # With knot_transits the knots are placed by epochs that stay on the workers
    # (primary_knots.ClusterEpochs): counts and order statistics as of one sorted array,
    # through buckets of time small enough here to cut the epochs many times, one of them a
    # single bin over the bucket size (ties).
    from mcsweep.experiments.primary.knots import ClusterEpochs

    rng = np.random.default_rng(5)
    pieces = [np.sort(np.concatenate([rng.uniform(10.0, 20.0, n), np.full(300, 12.5)]))
              for n in (700, 0, 1500, 40)]
    whole = np.sort(np.concatenate(pieces))
    monkeypatch.setattr(ClusterEpochs, "BUCKET", 200)
    monkeypatch.setattr(ClusterEpochs, "BINS", 64)
    epochs = ClusterEpochs(client, [client.submit(np.copy, p, pure=False) for p in pieces], 10.0, 20.0)
    assert epochs.size == whole.size
    x = np.array([9.0, 10.5, 12.5, 12.5 + 1e-12, 19.99, 21.0])
    for side in ("left", "right"):
        np.testing.assert_array_equal(epochs.searchsorted(x, side), np.searchsorted(whole, x, side))
    ranks = np.array([0, 1, 199, 200, 201, 1000, 1234, whole.size - 1, 1000])
    np.testing.assert_array_equal(epochs.values(ranks), whole[ranks])


def test_outcome_lost_before_the_parts_are_read_solves_again(both, client, monkeypatch):
    # The per-star results are gathered part by part after the solution: a loss met there
    # (the stars' outcome went with a worker: ChunksLost, as DaskChunks raises it after
    # rebuilding the chunks; here raised once in place of a worker's death) solves the prior
    # again; the same bits.
    from mcsweep.experiments.primary import prior_solution as PS
    from mcsweep.solver.executors import ChunksLost

    settings, local, remote = both
    ref = solve_prior(settings, local, "F90").results.frame()
    real_solve, solves = PS.solve_global, []
    monkeypatch.setattr(PS, "solve_global", lambda *a, **k: solves.append(1) or real_solve(*a, **k))
    real_values, lost = PS.chunk_values, []

    def once_lost(run, fn, items):
        if fn is PS.outcome_slice and not lost:
            lost.append(1)
            raise ChunksLost("lost (simulated)")
        return real_values(run, fn, items)

    monkeypatch.setattr(PS, "chunk_values", once_lost)
    got = solve_prior(settings, remote, "F90", dask_client=client, chunk_stars=2 * BLOCK)
    frame = got.results.frame()
    assert lost and len(solves) == 2  # solved again after the loss
    np.testing.assert_array_equal(ref.to_numpy(), frame.to_numpy())


def test_cluster_built_data_are_the_driver_built_bits(both, client):
    settings, local, remote = both
    assert remote.on_cluster and not hasattr(remote, "h") and not local.on_cluster
    assert len(local.blocks) > 6  # several blocks, chunks of two, partitions across them
    # the driver holds no star: only counts
    assert not any(hasattr(remote, name) for name in ("stars", "solved", "normals", "x_true"))
    assert (remote.n_stars, remote.n_solved, remote.n_fov_transits) == (local.n_stars, local.n_solved,
                                                                         local.n_fov_transits)
    for a, b in zip(remote.spline.segment_knots, local.spline.segment_knots, strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(remote.covered, local.covered)
    assert remote.n_measurements == local.n_measurements
    assert [(s.first, s.n, s.rows) for s in remote.blocks] == [(b.first, b.n, b.rows) for b in local.blocks]
    # the band the driver got from the chunks' sums is the one of the blocks, bit for bit
    prior = np.array([0.0, 0.0, 1.0, 1.0, 1.0])
    np.testing.assert_array_equal(remote.naa_band, local.problem(prior).naa_band)
    assert local.problem(prior).leaf > 1
    # each block, its measurements, its stars' data normal matrices and truth, as kept on the workers
    ranges = [tuple(r) for r in remote.ranges]
    chunks = client.gather(remote.chunks.futures)
    for (lo, hi), (blocks, hs, kept) in zip(ranges, chunks, strict=True):
        stars = slice(local.blocks[lo].first, local.blocks[hi - 1].first + local.blocks[hi - 1].n)
        np.testing.assert_array_equal(kept["normals"], local.normals[stars])
        np.testing.assert_array_equal(kept["x_true"], local.x_true[stars])
        np.testing.assert_array_equal(kept["star"], local.solved[stars])
        # each star's mean live epoch (evaluation_epoch='star_mean'), by the driver's formula
        np.testing.assert_array_equal((kept["mean_tcb_jd"] - local.t_ref_jd) / JULIAN_YEAR_DAYS,
                                      local.stars["epoch_offset_yr"].to_numpy()[local.solved[stars]])
        for blk, h, ref in zip(blocks, hs, local.blocks[lo:hi], strict=True):
            np.testing.assert_array_equal(h, local.h[ref.rows])
            for f in ("star", "src", "t", "pq", "j0", "bval", "seg", "seg_j0"):
                np.testing.assert_array_equal(getattr(blk, f), getattr(ref, f))


def test_cluster_built_solution_is_the_forked_one(both, client, monkeypatch):
    settings, local, remote = both
    ref = solve_prior(settings, local, "F90", workers=2)
    got = solve_prior(settings, remote, "F90", dask_client=client, chunk_stars=2 * BLOCK)
    assert ref[2]["iterations"] == got[2]["iterations"] > 5
    assert ref[2]["attitude_rms_uas"] == got[2]["attitude_rms_uas"]
    np.testing.assert_array_equal(ref[0].frame().to_numpy(), got[0].frame().to_numpy())
    np.testing.assert_array_equal(ref[3].to_numpy(), got[3].to_numpy())
    np.testing.assert_array_equal(ref.attitude, got.attitude)
    with pytest.raises(ValueError, match="dask_client"):
        solve_prior(settings, remote, "F90")
    # the next prior from this one's attitude (solver_start='previous'), sent to the workers' setup
    ref = solve_prior(settings, local, "10F90", workers=2, attitude_start=ref.attitude)
    got = solve_prior(settings, remote, "10F90", dask_client=client, chunk_stars=2 * BLOCK,
                        attitude_start=got.attitude)
    assert ref.extra["iterations"] == got.extra["iterations"]
    np.testing.assert_array_equal(ref.results.frame().to_numpy(), got.results.frame().to_numpy())
    np.testing.assert_array_equal(ref.attitude, got.attitude)
    # parts of 700 stars: each gathered from the partitions and chunks that hold its stars
    monkeypatch.setattr(primary_results, "PART_STARS", 700)
    parts = list(got.results.parts())
    assert [len(p) for p in parts] == [700, 700, 700, len(local.stars) - 2100]
    np.testing.assert_array_equal(pd.concat(parts, ignore_index=True).to_numpy(), ref.results.frame().to_numpy())


def test_positions_at_each_stars_own_epoch_on_the_cluster_are_the_forked_ones(both, client):
    # evaluation_epoch='star_mean' (Sect. 2.1's "mean epoch of observation" per star): the
    # cluster attaches each star's
    # epoch offset on its worker; the local path reads it from the driver's table
    settings, local, remote = both
    own = dataclasses.replace(settings, evaluation_epoch="star_mean")
    ref = solve_prior(own, local, "F90", workers=2)
    got = solve_prior(own, remote, "F90", dask_client=client, chunk_stars=2 * BLOCK)
    np.testing.assert_array_equal(ref.results.frame().to_numpy(), got.results.frame().to_numpy())
    common = solve_prior(settings, remote, "F90", dask_client=client, chunk_stars=2 * BLOCK)
    np.testing.assert_array_equal(common.attitude, got.attitude)  # the solution is the same ...
    moved = got.results.frame()["err_mas"].to_numpy() != common.results.frame()["err_mas"].to_numpy()
    assert np.count_nonzero(moved) > len(moved) // 2  # ... its positions are referred elsewhere


def test_cluster_built_solution_survives_a_killed_worker(both, client, kill_worker_at):
    # A worker killed mid-solve takes its chunks and the inputs scattered to it: the chunks
    # are built again from the driver's per-star arrays and the solution restarts, same bits.
    settings, local, remote = both
    ref = solve_prior(settings, local, "10F90")
    client.wait_for_workers(2, timeout=60)
    log = kill_worker_at(3)
    got = solve_prior(settings, remote, "10F90", dask_client=client, chunk_stars=2 * BLOCK, log=log)
    client.wait_for_workers(2, timeout=60)  # the nanny restarts it for the next test
    assert log.killed
    assert ref[2]["iterations"] == got[2]["iterations"]
    np.testing.assert_array_equal(ref[0].frame().to_numpy(), got[0].frame().to_numpy())
    np.testing.assert_array_equal(ref[3].to_numpy(), got[3].to_numpy())


def test_worker_lost_after_the_solution_restarts_it(both, client, monkeypatch):
    # Killed after the PCG loop, before the frame fit and the evaluation: the stars' solution
    # went with the worker, so the whole sequence restarts on rebuilt chunks; same bits.
    import os
    import signal

    from mcsweep.experiments.primary import prior_solution as PS

    settings, local, remote = both
    ref = solve_prior(settings, local, "F90")
    client.wait_for_workers(2, timeout=60)
    victim = sorted(client.run(os.getpid).values())[0]
    real, calls = PS.solve_global, []

    def solve_then_kill(*args, **kwargs):
        sol = real(*args, **kwargs)
        if not calls:
            os.kill(victim, signal.SIGKILL)
        calls.append(1)
        return sol

    monkeypatch.setattr(PS, "solve_global", solve_then_kill)
    got = solve_prior(settings, remote, "F90", dask_client=client, chunk_stars=2 * BLOCK)
    client.wait_for_workers(2, timeout=60)
    assert len(calls) == 2  # solved again after the loss
    np.testing.assert_array_equal(ref[0].frame().to_numpy(), got[0].frame().to_numpy())
    np.testing.assert_array_equal(ref[3].to_numpy(), got[3].to_numpy())
    assert ref[2]["attitude_rms_uas"] == got[2]["attitude_rms_uas"]
