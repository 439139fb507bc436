"""validation.dr3_colours: the comparison's bookkeeping against hand-made tables, and its
command's bad input (one line, exit status 2, nothing computed)."""

import numpy as np
import pandas as pd
import pytest

from mcsweep.validation import dr3_colours as dc


def _table(model_scale):
    row = dict(g="5-6", b="0-15")
    for who, s in (("dr3", 1.0), ("model", model_scale)):
        row.update({f"{who}_q10": 0.1, f"{who}_q50": 1.1, f"{who}_q90": 2.3, f"{who}_red": 0.45})
        row.update({f"{who}_n_{t}": 100.0 * s for t in dc.TERCILES})
    return pd.DataFrame([row])


def test_misfit_is_the_rms_of_log_count_ratios_and_targets_follow_the_tolerances():
    t = _table(1.2)
    assert dc.tercile_misfit(t) == pytest.approx(np.log(1.2), rel=1e-12)
    met = dc.targets_met(t)
    assert met[["q10", "q50", "q90", "red"]].all(axis=None) and not met["counts"].item()
    assert dc.targets_met(_table(1.05))["counts"].item()


@pytest.mark.parametrize("args, word", [
    (["--fit", "--giant", "0.5,x"], "--giant"),
    (["--fit", "--young", "-1"], "--young"),
    (["--out", "/nonexistent/folder/t.csv"], "--out"),
])
def test_bad_input_is_one_line_and_status_2(capsys, args, word):
    assert dc.main(args) == 2
    err = capsys.readouterr().err.strip()
    assert word in err and "\n" not in err
