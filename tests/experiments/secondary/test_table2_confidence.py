"""Table 2's headings and error percentile follow the run's confidence level and dilution.

Formerly the headings hard-coded "95 %" (the paper's dilution) and the error column stayed
the 90th percentile whatever ``confidence`` was. The paper's F90 prior makes the P
ellipse match the P-th percentile of the actual errors (Sect. 3.3), so a run at P
reports the 100 P-th percentile.
"""

import math

import numpy as np
import pandas as pd
import pytest

from mcsweep.experiments.secondary.table import (SOLUTION_COLUMNS, no_prior_rows, table2_layout,
                                                 table2_markdown, table2_rows)

N = 101
#: The percentile label and the interpolated percentile: two float paths to 100 P.
RTOL_PATHS = 1e-12


def _stars() -> pd.DataFrame:
    # Errors 0, 1, ..., 100 mas in each subset: the q-th percentile (linear interpolation,
    # numpy's default) is exactly q mas, a closed form independent of the code.
    d = {"n_fov": np.r_[np.full(N, 3), np.full(N, 9)]}
    for col in SOLUTION_COLUMNS.values():
        d[f"inside_{col}"] = np.r_[np.ones(N), np.zeros(N)].astype(int)
        d[f"err_{col}_mas"] = np.r_[np.arange(N), np.arange(N)].astype(float)
    return pd.DataFrame(d)


@pytest.mark.parametrize("p", [0.8, 0.9, 0.95])
def test_error_percentile_is_100_p(p):
    t = table2_rows([(15.0, _stars())], p)
    np.testing.assert_allclose(t["error_percentile"], 100 * p, rtol=RTOL_PATHS, atol=0)
    np.testing.assert_allclose(t["p90_error_mas"], 100 * p, rtol=RTOL_PATHS, atol=0)
    n = no_prior_rows([(15.0, _stars())], p)
    np.testing.assert_allclose(n["p90_error_mas"], 100 * p, rtol=RTOL_PATHS, atol=0)


def test_paper_values_only_at_the_papers_p():
    at_09 = table2_rows([(15.0, _stars())], 0.9)
    assert at_09["paper_p90_error_mas"].notna().all()
    at_08 = table2_rows([(15.0, _stars())], 0.8)
    assert at_08["paper_p90_error_mas"].isna().all() and at_08["paper_fraction_inside"].isna().all()


def test_headings_say_the_runs_p_and_dilution():
    t = table2_rows([(15.0, _stars())], 0.8)
    cols = list(table2_layout(t, 0.8)["<=4"].columns)
    assert "in 80 % ellipse, G~15 [%]" in cols and "p80 error, G~15 [mas]" in cols
    assert not any("90" in c for c in cols)
    md = table2_markdown(t, 0.8, dilution=0.9)
    assert md.splitlines()[0].startswith("# Table 2: stars with 90 % diluted") and "95 %" not in md
    assert "p80 error" in md and not math.isnan(t["fraction_inside"].iloc[0])
