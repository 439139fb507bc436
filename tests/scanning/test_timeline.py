"""Dead time and dilution draws."""

import numpy as np
import pytest

from mcsweep.scanning.timeline import (DeadTime, draw_dead_time, dilution_key, keep_after_dilution,
                                       splitmix64)

DAY_TOLERANCE = 1e-9  # day


def test_splitmix64_matches_the_published_sequence():
    # SplitMix64 seeded with 0 outputs 0xE220A8397B1DCDAF, 0x6E789E6AA1B965F4, ... (Vigna's
    # reference implementation); its n-th output is the finaliser of n * golden gamma.
    gamma = np.uint64(0x9E3779B97F4A7C15)
    with np.errstate(over="ignore"):
        states = np.arange(2, dtype=np.uint64) * gamma
    assert splitmix64(states).tolist() == [0xE220A8397B1DCDAF, 0x6E789E6AA1B965F4]


def test_dead_blocks_cover_the_requested_fraction_without_overlap():
    rng = np.random.default_rng(0)
    dead = draw_dead_time(2457000.0, 2457365.25, 0.2, outage_days=0.25, rng=rng)
    n_blocks = int(np.ceil(365.25 / 0.25))
    assert dead.starts.size == round(0.2 * n_blocks)
    assert np.all(np.diff(dead.starts) >= 0.25 - DAY_TOLERANCE)
    assert dead.total_days == pytest.approx(0.2 * 365.25, abs=0.25)
    assert dead.starts.min() >= 2457000.0 and dead.stops.max() <= 2457365.25


def test_is_dead_on_interval_edges():
    dead = DeadTime(np.array([10.0, 20.0]), np.array([11.0, 21.0]))
    t = np.array([9.999, 10.0, 10.5, 11.0, 15.0, 20.0, 21.0, 30.0])
    assert dead.is_dead(t).tolist() == [False, True, True, False, False, True, False, False]
    assert not DeadTime(np.empty(0), np.empty(0)).is_dead(t).any()


def test_no_draw_without_dead_time():
    rng = np.random.default_rng(5)
    state = rng.bit_generator.state
    assert draw_dead_time(0.0, 10.0, 0.0, outage_days=1.0, rng=rng).starts.size == 0
    assert rng.bit_generator.state == state


def test_dilution_is_uniform_and_keyed():
    key = dilution_key(np.random.default_rng(1))
    n = 200_000
    src = np.repeat(np.arange(n // 100), 100)
    t = 2457000.0 + np.tile(np.arange(100) * 0.25, n // 100)
    is_f = np.tile(np.arange(100) % 2 == 1, n // 100)
    keep = keep_after_dilution(key, src, is_f, t, 0.95)
    sigma = np.sqrt(0.05 * 0.95 / n)
    assert abs(keep.mean() - 0.05) < 5 * sigma
    # same transit, same draw, whatever else is in the batch and in which order
    perm = np.random.default_rng(2).permutation(n)
    np.testing.assert_array_equal(keep_after_dilution(key, src[perm], is_f[perm], t[perm], 0.95), keep[perm])
    # P and F of the same hour, and neighbouring sources, are drawn independently
    other = keep_after_dilution(key, src, ~is_f, t, 0.95)
    assert abs(np.mean(keep & other) - 0.05**2) < 5 * np.sqrt(0.0025 / n)
