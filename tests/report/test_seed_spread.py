"""Two-seed comparison against a synthetic sweep whose Monte Carlo noise is known."""

import math

import numpy as np
import pandas as pd

from mcsweep.validation.seed_spread import EXPECTED_INSIDE, seed_spread

N_CELLS = 4000
NOISE_DEX = 0.02


def _run(rng, mu):
    x = mu + NOISE_DEX * rng.normal(size=N_CELLS)
    return pd.DataFrame({"cell_id": np.arange(N_CELLS), "g_min": 6.0 + (np.arange(N_CELLS) % 2), "g_max": 0.0,
                         "f90_flag": "ok", "sigma_f90_mas": 10 ** x, "sigma_f90_lo_mas": 10 ** (x - NOISE_DEX),
                         "sigma_f90_hi_mas": 10 ** (x + NOISE_DEX)})


def test_seed_spread_recovers_the_noise_of_one_run():
    rng = np.random.default_rng(2)
    mu = rng.normal(size=N_CELLS)
    a, b = _run(rng, mu), _run(rng, mu)
    b.loc[0, "f90_flag"] = "never_reached"  # left out
    t = seed_spread(a, b).set_index("g_bin")
    assert t.loc["all", "n_cells"] == N_CELLS - 1
    # Statistical tolerances: 4 standard errors of an RMS (relative 1/sqrt(2N)) and of a
    # binomial fraction.
    assert abs(t.loc["all", "one_run_noise_dex"] / NOISE_DEX - 1) < 4 / math.sqrt(2 * N_CELLS)
    assert abs(t.loc["all", "median_half_width_dex"] - NOISE_DEX) < 1e-12
    assert abs(t.loc["all", "fraction_b_inside_a"] - EXPECTED_INSIDE) < 4 * math.sqrt(0.25 / N_CELLS)
    assert math.isclose(EXPECTED_INSIDE, math.erf(0.5), abs_tol=1e-4)


def test_missing_run_is_one_line_and_exit_2(tmp_path, capsys):
    from mcsweep.validation.seed_spread import main

    good = tmp_path / "a"
    good.mkdir()
    _run(np.random.default_rng(1), np.zeros(N_CELLS)).to_csv(good / "f90_cells.csv", index=False)
    bad = tmp_path / "b"
    bad.mkdir()
    pd.DataFrame({"cell_id": [1]}).to_csv(bad / "f90_cells.csv", index=False)
    for other, needle in ((tmp_path / "missing", "missing"), (bad, "sigma_f90_mas")):
        assert main([str(good), str(other)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and needle in err[0], err
