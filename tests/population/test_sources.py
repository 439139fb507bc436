"""make_source and the population config group files."""

from importlib import resources

import numpy as np
import pandas as pd
import pytest
from omegaconf import OmegaConf

from mcsweep.errors import UserInputError
from mcsweep.population import CatalogueSource, GalaxyModel, PopulationSource, make_source
from mcsweep.population.galaxy import DEFAULT_PARAMS
from mcsweep.population.sources import CATALOGUE_KEYS


def _group(name):
    text = resources.files("mcsweep.conf").joinpath(f"population/{name}.yaml").read_text()
    return OmegaConf.create(text)


def test_galaxy_model_yaml_lists_every_parameter_at_its_default():
    cfg = _group("galaxy_model")
    d = OmegaConf.to_container(cfg)
    assert d.pop("name") == "galaxy_model"
    params = d.pop("params")
    assert not d
    assert set(params) == set(DEFAULT_PARAMS)
    for k, v in params.items():
        assert v == DEFAULT_PARAMS[k], k
    src = make_source(cfg)
    assert isinstance(src, GalaxyModel) and isinstance(src, PopulationSource)


def test_catalogue_yaml_keys_and_required_path(tmp_path):
    cfg = _group("catalogue")
    assert set(cfg) - {"name"} == set(CATALOGUE_KEYS)
    assert OmegaConf.is_missing(cfg, "path")
    path = tmp_path / "s.csv"
    pd.DataFrame({"ra": [157.5], "dec": [0.0], "parallax": [1.0], "pmra": [1.0], "pmdec": [2.0],
                  "phot_g_mean_mag": [15.0]}).to_csv(path, index=False)
    cfg.path = str(path)
    src = make_source(cfg)
    assert isinstance(src, CatalogueSource) and isinstance(src, PopulationSource)
    assert len(src.sample_cone(245.7, 46.5, 1.0, 14.5, 15.5, np.random.default_rng(0))) == 1


def test_overrides_and_nested_params():
    m = make_source({"name": "galaxy_model", "extinction": False,
                     "params": {"thin_disc_scale_height_factor": 0.9}})
    assert m.params["extinction"] is False and m.params["thin_disc_scale_height_factor"] == 0.9
    # a schema carrying every key of the group, unset, is accepted
    m = make_source({"name": "galaxy_model", "path": None, "format": "auto", "columns": {},
                     "params": {}})
    assert isinstance(m, GalaxyModel)
    # ... also frozen into (key, value) pairs and tuples, as a cache key
    m = make_source({"name": "galaxy_model", "path": None, "format": "auto", "columns": (),
                     "params": (("components", ("thin_disc", "halo")), ("extinction", False))})
    assert m.params["components"] == ["thin_disc", "halo"] and m.params["extinction"] is False


@pytest.mark.parametrize("cfg, match", [
    ({"name": "gums"}, "population='gums'"),
    ({"name": "catalogue"}, "population.path"),
    ({"name": "catalogue", "path": "x.csv", "colour": "red"}, "colour"),
    ({"name": "galaxy_model", "r0": 8}, "r0"),
    ("galaxy_model", "mapping"),
])
def test_bad_configs(cfg, match):
    with pytest.raises(UserInputError, match=match):
        make_source(cfg)
