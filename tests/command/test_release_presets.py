"""observations=dr1..dr5: each preset's span (the data releases' observation spans,
scanning-law-history.md), for the sweep and the global experiments."""

import pytest

from mcsweep.command.validate import compose_config, to_config
from mcsweep.experiments.global_solution.settings import global_fields
from mcsweep.scanning.segments import DATA_RELEASE_SPANS
from mcsweep.scanning.timescale import tcb_jd

# The note's spans (scanning-law-history.md): all from the start of routine operations.
SPANS = {"dr1": "2015-09-16", "dr2": "2016-05-23", "dr3": "2017-05-28", "dr4": "2020-01-20", "dr5": "2025-01-15"}


def _config(overrides):
    return to_config(compose_config(overrides))


@pytest.mark.parametrize("name", sorted(SPANS))
@pytest.mark.parametrize("experiment", ["f90_sweep", "secondary", "primary"])
def test_each_preset_sets_the_release_span(name, experiment):
    config = _config([f"observations={name}", f"experiment={experiment}"])
    assert (config.observations.start, config.observations.end[:10]) == ("2014-07-25T10:30:00", SPANS[name])
    assert (config.observations.start, config.observations.end) == DATA_RELEASE_SPANS[name]
    if experiment != "f90_sweep":
        fields = global_fields(config, experiment)
        assert fields["start_jd"] == tcb_jd("2014-07-25T10:30:00", "s")
        assert fields["end_jd"] == tcb_jd(DATA_RELEASE_SPANS[name][1], "e")
        # Inside the flown law's validity: nothing extrapolated.
        assert fields["law"].extrapolation_note(fields["start_jd"], fields["end_jd"]) is None


def test_default_window_and_missions_are_unchanged():
    config = _config([])
    assert (config.observations.start, config.observations.end) == ("2014-10-01T00:00:00", "2016-01-01T00:00:00")
    sec = global_fields(_config(["experiment=secondary"]), "secondary")
    assert sec["end_jd"] - sec["start_jd"] == pytest.approx(5 * 365.25)
    # Table 2's five years run to 2019-07-25, past no end of the flown law: not extrapolated.
    assert sec["law"].extrapolation_note(sec["start_jd"], sec["end_jd"]) is None
