"""Settings an experiment never reads: a one-line warning, and the config hash does not move."""

import subprocess
import sys
from pathlib import Path

from omegaconf import OmegaConf

from mcsweep.command.provenance import config_hash
from mcsweep.command.validate import compose_config, ignored_settings, preflight
from mcsweep.population.galaxy.model import PARAMS_R03_5

BIN = Path(sys.executable).parent
IGNORED = ["sky=single", "cell.max_stars=77", "prior_grid.n=5", "observations.f90_case=one",
           "magnitudes=g15", "experiment.showcase.enabled=false"]


def _hash(overrides):
    return config_hash(OmegaConf.to_container(compose_config(overrides), resolve=True))


#: The galaxy model the hashes below were recorded under (besancon-r03-5; its defaults then).
R03_5 = [f"population.params.{k}={v}" for k, v in PARAMS_R03_5.items()]


def test_ignored_settings_do_not_change_the_secondary_hash():
    base = _hash(["experiment=secondary"])
    for ov in IGNORED:
        assert _hash(["experiment=secondary", ov]) == base, ov
    # ... while the settings it reads do, and the sweep still hashes everything it reads.
    assert _hash(["experiment=secondary", "confidence=0.8"]) != base
    assert _hash(["experiment=secondary", "experiment.secondary.dilution=0.9"]) != base
    assert _hash(["sky=single"]) != _hash([])


def test_zero_noise_floor_keeps_the_hash_of_configs_made_before_the_option():
    cfg = OmegaConf.to_container(compose_config(["experiment=secondary"]), resolve=True)
    assert cfg["noise"]["al_floor_mas"] == 0.0
    before = {**cfg, "noise": {k: v for k, v in cfg["noise"].items() if k != "al_floor_mas"}}
    assert config_hash(cfg) == config_hash(before)
    assert _hash(["experiment=secondary", "noise=edr3_floor"]) != config_hash(cfg)
    assert _hash(["experiment=secondary", "noise.al_floor_mas=0.039"]) != config_hash(cfg)


def test_giant_thickness_of_r03_4_keeps_the_hash_of_configs_made_before_the_option():
    cfg = OmegaConf.to_container(compose_config(R03_5), resolve=True)
    params = cfg["population"]["params"]
    assert params["giant_thickness_factor"] == 0.45
    before = {**cfg, "population": {**cfg["population"], "params": {
        k: v for k, v in params.items() if k != "giant_thickness_factor"}}}
    assert config_hash(cfg) == config_hash(before)
    assert _hash(R03_5 + ["population.params.giant_thickness_factor=0.6"]) != config_hash(cfg)


def test_the_r03_5_preset_is_that_model_and_resumes_its_runs():
    # population=galaxy_model_r03_5: r03-5's parameters, and the hash its default runs were made with
    params = OmegaConf.to_container(compose_config(["population=galaxy_model_r03_5"]), resolve=True)["population"]
    assert params["name"] == "galaxy_model"
    assert {k: params["params"][k] for k in PARAMS_R03_5} == PARAMS_R03_5
    assert _hash(["population=galaxy_model_r03_5"]) == "285a027a54185cfd"
    assert _hash(["population=galaxy_model_r03_5", "experiment=primary"]) == "13a87abc2770018d"


def test_the_r03_5_model_keeps_its_hash_and_the_r03_6_defaults_get_a_new_one():
    # besancon-r03-6 added two keys (evolved_stars, young_disc_thickness_factor) and changed two
    # defaults (the giants' and the thin disc's thickness): r03-5's values give the default sweep's
    # hash pinned at 66652ca, without the new keys as with them; the new defaults another
    cfg = OmegaConf.to_container(compose_config(R03_5), resolve=True)
    params = cfg["population"]["params"]
    before = {**cfg, "population": {**cfg["population"], "params": {
        k: v for k, v in params.items() if k not in ("evolved_stars", "young_disc_thickness_factor")}}}
    assert config_hash(cfg) == config_hash(before) == "285a027a54185cfd"
    new = OmegaConf.to_container(compose_config([]), resolve=True)["population"]["params"]
    assert (new["evolved_stars"], new["young_disc_thickness_factor"]) == ("parsec", 0.65)
    assert _hash([]) != config_hash(cfg)


def test_the_r03_4_model_keeps_its_hash_and_the_r03_5_defaults_get_a_new_one():
    # besancon-r03-5 changed two defaults: runs made before under the old ones resume when the
    # old values are given, and are refused under the new defaults
    cfg = OmegaConf.to_container(compose_config(["population.params.extinction_model=disc",
                                                 "population.params.subgiants=false"]), resolve=True)
    params = cfg["population"]["params"]
    before = {**cfg, "population": {**cfg["population"], "params": {
        k: v for k, v in params.items() if k not in ("extinction_model", "subgiants")}}}
    assert config_hash(cfg) == config_hash(before)
    new = OmegaConf.to_container(compose_config([]), resolve=True)["population"]["params"]
    assert (new["extinction_model"], new["subgiants"]) == ("arenou1992", True)
    assert _hash([]) != config_hash(cfg)


def test_a_solution_from_zero_keeps_the_hash_of_configs_made_before_the_start_option():
    # Primary runs made before experiment.primary.solver_start solved every prior from zero:
    # they resume under solver_start=zero, and are refused under the new default 'previous'.
    cfg = OmegaConf.to_container(compose_config(["experiment=primary", "experiment.primary.solver_start=zero"]),
                                 resolve=True)
    primary = cfg["experiment"]["primary"]
    before = {**cfg, "experiment": {**cfg["experiment"], "primary": {
        k: v for k, v in primary.items() if k != "solver_start"}}}
    assert config_hash(cfg) == config_hash(before)
    assert _hash(["experiment=primary"]) != config_hash(cfg)


def test_subsets_of_live_transits_keep_the_hash_of_configs_made_before_the_option():
    cfg = OmegaConf.to_container(compose_config(["experiment=primary"]), resolve=True)
    primary = cfg["experiment"]["primary"]
    assert primary["subset_transits"] == "live"
    before = {**cfg, "experiment": {**cfg["experiment"], "primary": {
        k: v for k, v in primary.items() if k != "subset_transits"}}}
    assert config_hash(cfg) == config_hash(before)
    assert _hash(["experiment=primary", "experiment.primary.subset_transits=scheduled"]) != config_hash(cfg)


def test_knots_by_equal_counts_keep_the_hash_of_configs_made_before_the_knot_rule():
    # Runs with knot_transits made before experiment.primary.knot_rule placed knots by equal
    # counts: they resume under knot_rule=counts and are refused under the default 'uniform'.
    cfg = OmegaConf.to_container(compose_config(["experiment=primary", "experiment.primary.knot_transits=25",
                                                 "experiment.primary.knot_rule=counts"]), resolve=True)
    primary = cfg["experiment"]["primary"]
    before = {**cfg, "experiment": {**cfg["experiment"], "primary": {
        k: v for k, v in primary.items() if k != "knot_rule"}}}
    assert config_hash(cfg) == config_hash(before)
    assert _hash(["experiment=primary", "experiment.primary.knot_transits=25"]) != config_hash(cfg)


def test_the_knot_rule_does_not_move_the_hash_of_runs_without_knot_transits():
    # 3 h knots (the default) never read the knot rule: any value, or none, is one config.
    cfg = OmegaConf.to_container(compose_config(["experiment=primary"]), resolve=True)
    primary = cfg["experiment"]["primary"]
    assert primary["knot_transits"] is None and primary["knot_rule"] == "uniform"
    before = {**cfg, "experiment": {**cfg["experiment"], "primary": {
        k: v for k, v in primary.items() if k != "knot_rule"}}}
    assert config_hash(before) == config_hash(cfg) == _hash(["experiment=primary", "experiment.primary.knot_rule=counts"])


def test_ignored_settings_get_one_warning_line_per_experiment():
    argv = ["experiment=secondary", *IGNORED, "confidence=0.8"]
    lines = ignored_settings(argv, preflight(argv))
    assert len(lines) == 1
    assert all(ov in lines[0] for ov in IGNORED) and "confidence" not in lines[0]
    assert ignored_settings(["sky=single"], preflight(["sky=single"])) == []


def test_multirun_warns_only_for_the_jobs_that_ignore():
    argv = ["-m", "experiment=f90_sweep,secondary", "sky=single"]
    lines = ignored_settings(argv, preflight(argv))
    assert lines == ["experiment=secondary ignores sky=single: they change neither its results nor its config hash"]


def test_cli_prints_the_warning_once_before_running(tmp_path):
    r = subprocess.run([str(BIN / "mcsweep"), f"hydra.run.dir={tmp_path / 'run'}", "experiment=secondary",
                        "sky=single", "cell.max_stars=7", "population=catalogue", "population.path=typo.fits"],
                       capture_output=True, text=True, timeout=120)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2, r.stderr[-2000:]
    assert lines[0] == ("mcsweep: warning: experiment=secondary ignores sky=single, cell.max_stars=7: they change "
                        "neither its results nor its config hash")
    assert len(lines) == 2 and "typo.fits" in lines[1]


def test_same_values_under_an_older_hash_rule_are_explained(tmp_path):
    import json

    import pytest

    from mcsweep.errors import UserInputError
    from mcsweep.command.provenance import Provenance

    (tmp_path / "provenance.json").write_text(json.dumps({"config_hash": "0ld", "config": {"seed": 1},
                                                          "mcsweep_version": "0.1"}))
    with pytest.raises(UserInputError, match="same values, hash 0ld by 0.1"):
        Provenance(tmp_path, {"seed": 1}, kind="secondary").check_compatible()


def test_a_refusal_names_both_values_of_a_changed_default(tmp_path):
    # a run made under r03-4's defaults (the keys left out of its science part) refused under
    # r03-5's: the line names the old and the new value, not None
    import json

    import pytest

    from mcsweep.errors import UserInputError
    from mcsweep.command.provenance import Provenance

    old = OmegaConf.to_container(compose_config(["population.params.extinction_model=disc",
                                                 "population.params.subgiants=false"]), resolve=True)
    (tmp_path / "provenance.json").write_text(json.dumps({"config_hash": config_hash(old), "config": old}))
    new = OmegaConf.to_container(compose_config([]), resolve=True)
    with pytest.raises(UserInputError, match="extinction_model: 'disc' -> 'arenou1992'; "
                                             "population.params.subgiants: False -> True"):
        Provenance(tmp_path, new, kind="f90_sweep").check_compatible()


def test_a_refusal_names_the_knot_rule_only_where_it_has_an_effect(tmp_path):
    # 3 h knots (no knot_transits) resumed with knot_transits=25: the line names knot_transits
    # and the rule now in effect, not a rule the old run never used
    import json

    import pytest

    from mcsweep.errors import UserInputError
    from mcsweep.command.provenance import Provenance

    old = OmegaConf.to_container(compose_config(["experiment=primary"]), resolve=True)
    del old["experiment"]["primary"]["knot_rule"]  # a run made before the option
    (tmp_path / "provenance.json").write_text(json.dumps({"config_hash": config_hash(old), "config": old}))
    new = OmegaConf.to_container(compose_config(["experiment=primary", "experiment.primary.knot_transits=25"]),
                                 resolve=True)
    with pytest.raises(UserInputError) as refused:
        Provenance(tmp_path, new, kind="primary").check_compatible()
    assert "knot_transits: None -> 25" in str(refused.value)
    assert "knot_rule: None -> 'uniform'" in str(refused.value) and "'counts'" not in str(refused.value)


#: Config hashes computed by mcsweep at commit 66652ca, before the reversed-precession year
#: of the flown law was refitted: runs whose transits all fall before 2019-07-05 must keep
#: them (and resume), runs that read the year must not.
HASHES_BEFORE_THE_REFIT = {
    (): "285a027a54185cfd",                                   # the default sweep, Oct 2014 - 2015
    ("experiment=primary",): "13a87abc2770018d",              # Table 3, one year from 2014-07-25
    ("experiment=real_sky",): "6163d0d02e11348f",
    ("observations=dr3",): "4ce02ffd0486d3fd",                # ends 2017-05-28
    ("experiment=secondary", "experiment.secondary.mission_years=4.9"): "2e5afdc73d73e902",
    ("experiment=secondary", "observations=dr3"): "84a7d15abfd09dbb",
}
#: ... and of runs that read it: Table 2's five years end 2019-07-25, 20 days into the year.
HASHES_THAT_READ_THE_REFITTED_YEAR = {
    ("observations=dr4",): "76982b2f62a4ec70",
    ("experiment=primary", "observations=dr4"): "b742c8cb4cc07fdf",
    ("experiment=secondary",): "55385ec494efabea",
}


def test_the_refitted_reversed_year_keeps_the_hash_of_runs_that_never_read_it():
    for overrides, before in HASHES_BEFORE_THE_REFIT.items():
        assert _hash(list(overrides) + R03_5) == before, overrides
    for overrides, before in HASHES_THAT_READ_THE_REFITTED_YEAR.items():
        assert _hash(list(overrides) + R03_5) != before, overrides


def test_a_run_that_read_the_refitted_year_is_refused_naming_the_segment(tmp_path):
    import json

    import pytest

    from mcsweep.errors import UserInputError
    from mcsweep.command.provenance import Provenance

    new = OmegaConf.to_container(compose_config(["observations=dr4"] + R03_5), resolve=True)
    old = json.loads(json.dumps(new))
    k = [s["kind"] for s in old["scanning"]["segments"]].index("nsl_reversed")
    old["scanning"]["segments"][k].update(nu_ref_deg=315.314, omega_ref_deg=169.887)
    assert config_hash(old) == HASHES_THAT_READ_THE_REFITTED_YEAR[("observations=dr4",)]
    (tmp_path / "provenance.json").write_text(json.dumps({"config_hash": config_hash(old), "config": old}))
    with pytest.raises(UserInputError) as refused:
        Provenance(tmp_path, new, kind="f90_sweep").check_compatible()
    message = str(refused.value)
    assert "\n" not in message
    assert (f"scanning.segments[{k}] (nsl_reversed 2019-07-05..2020-08-01).nu_ref_deg: 315.314 -> 314.6231; "
            f"scanning.segments[{k}] (nsl_reversed 2019-07-05..2020-08-01).omega_ref_deg: 169.887 -> 170.3941"
            ) in message
    # the same old run directory under a span that ends before the year: resumed
    short = OmegaConf.to_container(compose_config(["observations=dr3"] + R03_5), resolve=True)
    old_short = json.loads(json.dumps(short))
    old_short["scanning"]["segments"][k].update(nu_ref_deg=315.314, omega_ref_deg=169.887)
    (tmp_path / "provenance.json").write_text(json.dumps({"config_hash": config_hash(old_short),
                                                          "config": old_short}))
    Provenance(tmp_path, short, kind="f90_sweep").check_compatible()
