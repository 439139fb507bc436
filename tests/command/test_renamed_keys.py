"""A renamed config key keeps working under its old name: one warning line, the same
config, the same hash as before the rename, and a refusal that names the key as it is now."""

import json
import subprocess
import sys
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from mcsweep.command.provenance import Provenance, config_hash
from mcsweep.command.validate import compose_config
from mcsweep.errors import UserInputError
from mcsweep.population.galaxy.model import PARAMS_R03_5

BIN = Path(sys.executable).parent
#: Config hashes computed by mcsweep at commit 66652ca, when the keys had their old names.
HASHES_AT_66652CA = {
    ("experiment=primary", "experiment.primary.primary_sources=600"): "5c8e2452daaf2191",
    ("experiment=primary", "experiment.primary.primary_sources=600", "experiment.primary.primary_g_min=12.5"):
        "5e69fa97e881114d",
}
#: Computed at b6d24f5, when dead_time_outage_days was dead_time_block_days.
HASHES_AT_B6D24F5 = {
    ("experiment=primary",): "13a87abc2770018d",
    ("experiment=primary", "experiment.primary.dead_time_block_days=10"): "9307a92c71563cfa",
}
NEW_NAMES = {"primary_sources": "extra_sources", "primary_g_min": "extra_g_min",
             "dead_time_block_days": "dead_time_outage_days"}


#: The galaxy model the hashes below were recorded under (besancon-r03-5; its defaults then).
R03_5 = [f"population.params.{k}={v}" for k, v in PARAMS_R03_5.items()]


def _hash(overrides):
    return config_hash(OmegaConf.to_container(compose_config(list(overrides) + R03_5), resolve=True))


@pytest.mark.parametrize("old, pinned", [*HASHES_AT_66652CA.items(), *HASHES_AT_B6D24F5.items()])
def test_new_and_old_names_give_the_hash_from_before_the_rename(old, pinned):
    new = list(old)
    for before, after in NEW_NAMES.items():
        new = [o.replace(before, after) for o in new]
    assert _hash(new) == _hash(old) == pinned


def test_the_old_name_sets_the_new_key():
    cfg = compose_config(["experiment=primary", "experiment.primary.primary_sources=600"])
    assert cfg.experiment.primary.extra_sources == 600 and "primary_sources" not in cfg.experiment.primary


def test_the_command_warns_once_and_checks_the_value_under_the_new_name(tmp_path):
    r = subprocess.run([str(BIN / "mcsweep"), "experiment=primary", "experiment.primary.primary_sources=-1",
                        f"hydra.run.dir={tmp_path / 'run'}"], capture_output=True, text=True, timeout=120)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2 and not (tmp_path / "run").exists(), r.stderr
    assert lines == ["mcsweep: warning: experiment.primary.primary_sources is deprecated: use "
                     "experiment.primary.extra_sources (the same setting; the config hash does not change)",
                     "mcsweep: error: experiment.primary.extra_sources=-1 is not accepted; expected a number >= 0 "
                     "(0: the magnitude classes only, as the paper)"]


def test_a_run_made_under_the_old_name_is_refused_naming_the_new_one(tmp_path):
    old = OmegaConf.to_container(compose_config(["experiment=primary", "experiment.primary.extra_sources=600"]),
                                 resolve=True)
    old["experiment"]["primary"]["primary_sources"] = old["experiment"]["primary"].pop("extra_sources")
    (tmp_path / "provenance.json").write_text(json.dumps({"config_hash": config_hash(old), "config": old}))
    same = OmegaConf.to_container(compose_config(["experiment=primary", "experiment.primary.extra_sources=600"]),
                                  resolve=True)
    Provenance(tmp_path, same, kind="primary").check_compatible()  # resumes
    other = OmegaConf.to_container(compose_config(["experiment=primary", "experiment.primary.extra_sources=700"]),
                                   resolve=True)
    with pytest.raises(UserInputError, match=r"\(experiment\.primary\.extra_sources: 600 -> 700\)"):
        Provenance(tmp_path, other, kind="primary").check_compatible()
