"""Distinct-transit groups and their selection, against straightforward per-source loops."""

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcsweep.errors import UserInputError
from mcsweep.scanning import assign_groups, find_transits, group_summary, select_groups

LAG_D = 1.776 / 24  # day, Gamma / omega_z
SPIN_D = 6.0 / 24  # day


def _frame(rows):
    df = pd.DataFrame(rows, columns=["source_index", "tcb_jd", "fov"])
    df["group"] = assign_groups(df["source_index"], df["tcb_jd"], df["fov"] == "F", lag_days=LAG_D)
    df["scan_angle_deg"] = 0.0
    return df


def test_pairs_singles_and_successive_spins():
    t0 = 2457000.0
    df = _frame([
        (0, t0, "P"), (0, t0 + LAG_D, "F"),                     # a P+F pair -> group 0
        (0, t0 + SPIN_D, "P"), (0, t0 + SPIN_D + LAG_D, "F"),   # next spin: a new group
        (0, t0 + 20, "F"),                                      # F alone -> own group
        (0, t0 + 40, "P"),                                      # P alone -> own group
        (0, t0 + 40 + 3 * LAG_D, "F"),                          # F too late for that P
        (1, t0 + 5, "F"), (1, t0 + 5 + SPIN_D, "P"),            # new source restarts at 0
        (1, t0 + 5 + SPIN_D + LAG_D, "F"),
    ])
    assert df["group"].tolist() == [0, 0, 1, 1, 2, 3, 4, 0, 1, 1]
    summary = group_summary(df)
    assert summary["fovs"].tolist() == ["PF", "PF", "F", "P", "F", "F", "PF"]


def _reference_select(df, which):
    # Plain per-source loop: resolve negative indices against that source's group count.
    out = []
    for _, g in df.groupby("source_index", sort=True):
        n = g["group"].max() + 1
        wanted = {j if j >= 0 else n + j for j in which}
        out.append(g[g["group"].isin([w for w in wanted if 0 <= w < n])])
    return pd.concat(out)


@pytest.fixture(scope="module")
def diluted():
    rng = np.random.default_rng(12)
    ra, dec = rng.uniform(0, 360, 200), np.degrees(np.arcsin(rng.uniform(-1, 1, 200)))
    return find_transits(ra, dec, "2014-10-01", "2016-01-01", dilution=0.9, rng=np.random.default_rng(3))


@pytest.mark.parametrize("which", [[0], [0, 1], [0, -1], [1, 3, -2], [5, 6, 7], [-1]])
def test_select_groups_matches_a_per_source_loop(diluted, which):
    got = select_groups(diluted, which)
    ref = _reference_select(diluted, which)
    pd.testing.assert_frame_equal(got, ref)


def test_first_k_forms_agree_and_complete_drops_short_histories(diluted):
    a = select_groups(diluted, 3)
    pd.testing.assert_frame_equal(a, select_groups(diluted, "first 3"))
    pd.testing.assert_frame_equal(a, select_groups(diluted, [0, 1, 2]))
    full = select_groups(diluted, 3, complete=True)
    n_groups = diluted.groupby("source_index")["group"].max() + 1
    assert set(full["source_index"]) == set(n_groups.index[n_groups >= 3])
    assert set(full["source_index"]) < set(a["source_index"])  # some stars have < 3 groups
    pd.testing.assert_frame_equal(select_groups(diluted, "all"), diluted)


def test_first_and_last_of_a_single_group_star_is_that_group():
    df = _frame([(0, 2457000.0, "P"), (0, 2457000.0 + LAG_D, "F")])
    assert len(select_groups(df, [0, -1])) == 2
    assert len(select_groups(df, [0, -1], complete=True)) == 2


@pytest.mark.parametrize("which", ["first", "last 2", -1, 1.5, [0, "1"], None, True])
def test_bad_selection_raises_user_input_error(diluted, which):
    with pytest.raises(UserInputError):
        select_groups(diluted, which)


@settings(deadline=None)
@given(st.sets(st.tuples(st.integers(0, 3), st.integers(0, 400), st.booleans()), min_size=1, max_size=80),
       st.floats(-1e-4, 1e-4))
def test_groups_are_the_spins_a_source_was_seen_in(passages, jitter_d):
    # (source, spin number, is F): P at spin * 6 h, F one FoV lag later; the groups of a
    # source must be its distinct spins, numbered 0, 1, ... in time order.
    rows = sorted((src, spin * SPIN_D + (LAG_D if is_f else 0.0) + jitter_d, is_f, spin)
                  for src, spin, is_f in passages)
    src = np.array([r[0] for r in rows])
    t = 2457000.0 + np.array([r[1] for r in rows])
    is_f = np.array([r[2] for r in rows])
    spin = np.array([r[3] for r in rows])
    g = assign_groups(src, t, is_f, lag_days=LAG_D)
    for s in np.unique(src):
        expected = np.unique(spin[src == s], return_inverse=True)[1]
        np.testing.assert_array_equal(g[src == s], expected)
