"""Distinct-transit groups (visits) and their selection, against straightforward per-source loops."""

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcsweep.errors import UserInputError
from mcsweep.scanning import (
    VISIT_MAX_GAP_DAYS,
    VISIT_MAX_TURN_DEG,
    assign_groups,
    find_transits,
    group_summary,
    select_groups,
)

LAG_D = 1.776 / 24  # day, Gamma / omega_z
SPIN_D = 6.0 / 24  # day
VISIT_GAP_D = 2.0  # day, between the starts of successive visit slots


def _frame(rows):
    df = pd.DataFrame(rows, columns=["source_index", "tcb_jd", "fov", "scan_angle_deg"])
    df["group"] = assign_groups(df["source_index"], df["tcb_jd"], df["scan_angle_deg"])
    return df


def test_pairs_singles_successive_spins_and_turns():
    t0 = 2457000.0
    df = _frame([
        (0, t0, "P", 230.0), (0, t0 + LAG_D, "F", 230.2),        # a P+F pair -> group 0
        (0, t0 + SPIN_D, "P", 231.0),                            # next spin, same visit
        (0, t0 + SPIN_D + LAG_D, "F", 231.1),
        (0, t0 + 24, "F", 65.0),                                 # Table 1 #4 -> #5: 24 d later
        (0, t0 + 40, "P", 359.0), (0, t0 + 40 + LAG_D, "F", 1.0),  # angles wrap at 360 deg
        (0, t0 + 41.5, "P", 3.0),                                # 1.5 d after: a new visit
        (0, t0 + 41.5 + LAG_D, "F", 10.0),                       # 7 deg turn: a new direction
        (1, t0 + 5, "F", 10.0), (1, t0 + 5 + 2 * SPIN_D, "P", 11.0),  # spin lost to dead time
        (1, t0 + 5 + 2 * SPIN_D + LAG_D, "F", 11.2),
    ])
    assert df["group"].tolist() == [0, 0, 0, 0, 1, 2, 2, 3, 4, 0, 0, 0]
    summary = group_summary(df)
    assert summary["fovs"].tolist() == ["PFPF", "F", "PF", "P", "F", "FPF"]


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
    df = _frame([(0, 2457000.0, "P", 10.0), (0, 2457000.0 + LAG_D, "F", 10.1)])
    assert len(select_groups(df, [0, -1])) == 2
    assert len(select_groups(df, [0, -1], complete=True)) == 2


@pytest.mark.parametrize("which", ["first", "last 2", -1, 1.5, [0, "1"], None, True])
def test_bad_selection_raises_user_input_error(diluted, which):
    with pytest.raises(UserInputError):
        select_groups(diluted, which)


@settings(deadline=None)
@given(st.lists(st.tuples(st.integers(0, 3), st.integers(0, 60), st.integers(0, 3), st.booleans()),
                min_size=1, max_size=80))
def test_groups_are_the_visits_a_source_was_seen_in(passages):
    # (source, visit slot, spin within the visit, is F): visits start VISIT_GAP_D apart
    # (the flown law's shortest gap between visits is 2 days), spins 6 h apart inside a
    # visit, F one FoV lag after P; each visit has its own direction (wrapping through
    # 360 deg for some), turning 1 deg per spin (the precession's ~4 deg/day). The
    # groups of a source must be its distinct visits, numbered 0, 1, ... in time order.
    rows = sorted({(src, slot * VISIT_GAP_D + spin * SPIN_D + (LAG_D if is_f else 0.0),
                    (slot * 137.0 + src * 51.0 + spin * 1.0) % 360.0, slot)
                   for src, slot, spin, is_f in passages})
    src = np.array([r[0] for r in rows])
    t = 2457000.0 + np.array([r[1] for r in rows])
    psi = np.array([r[2] for r in rows])
    slot = np.array([r[3] for r in rows])
    g = assign_groups(src, t, psi)
    for s in np.unique(src):
        expected = np.unique(slot[src == s], return_inverse=True)[1]
        np.testing.assert_array_equal(g[src == s], expected)


def test_rule_sits_in_the_gap_between_visits_of_the_flown_law():
    # Independent of the grouping code: the raw times and scan angles of the flown law
    # over a sample of the sky. Consecutive transits closer than the rule's gap must be
    # one spin or less apart and turn little; all other gaps must be far longer.
    rng = np.random.default_rng(5)
    ra, dec = rng.uniform(0, 360, 60), np.degrees(np.arcsin(rng.uniform(-1, 1, 60)))
    tr = find_transits(ra, dec, "2014-10-01", "2016-01-01")
    same = np.diff(tr["source_index"].to_numpy()) == 0
    dt = np.diff(tr["tcb_jd"].to_numpy())[same]
    turn = np.abs(np.mod(np.diff(tr["scan_angle_deg"].to_numpy(float)) + 180.0, 360.0) - 180.0)[same]
    inside = dt <= VISIT_MAX_GAP_DAYS
    assert dt[inside].max() < SPIN_D * (1 + 1e-3)
    assert turn[inside].max() < VISIT_MAX_TURN_DEG / 2
    assert dt[~inside].min() > 1.5 * VISIT_MAX_GAP_DAYS
