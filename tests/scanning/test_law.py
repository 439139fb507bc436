"""ScanningLaw: presets in conf/scanning/, from_config, validation, Hydra composition."""

import dataclasses

import pytest
from omegaconf import OmegaConf

from mcsweep.errors import UserInputError
from mcsweep.scanning import ScanningLaw


def test_flown_preset_is_the_default_law():
    assert ScanningLaw.preset("flown") == ScanningLaw()
    law = ScanningLaw()
    assert (law.precession_S, law.spin_rate_arcsec_s) == (4.220747, 59.960499)
    assert (law.nu_ref_deg, law.omega_ref_deg) == (323.3708, 95.1324)
    assert law.ref_epoch_tcb == "2015-01-01T00:00:00"
    assert law.ac_limits_p_deg == (-0.41, 0.285) and law.ac_limits_f_deg == (-0.285, 0.41)


def test_from_config_accepts_omegaconf_and_lists_and_is_hashable():
    cfg = OmegaConf.create({"name": "x", "precession_S": 4.22, "ac_limits_p_deg": [-0.4, 0.3]})
    law = ScanningLaw.from_config(cfg)
    assert law.ac_limits_p_deg == (-0.4, 0.3) and law.precession_S == 4.22
    assert hash(law) == hash(ScanningLaw.from_config(dict(cfg)))
    # round trip through a plain dict of fields
    assert ScanningLaw.from_config(dataclasses.asdict(law)) == law


@pytest.mark.parametrize("mapping", [
    {"precesion_S": 4.2},
    {"precession_S": 0.5},
    {"solar_aspect_deg": 95.0},
    {"spin_rate_arcsec_s": -1.0},
    {"basic_angle_deg": "wide"},
    {"ac_limits_p_deg": [0.3, -0.4]},
    {"ac_limits_f_deg": [0.1]},
    {"ref_epoch_tcb": "first of May"},
    ["not", "a", "mapping"],
])
def test_bad_config_raises_user_input_error(mapping):
    with pytest.raises(UserInputError):
        ScanningLaw.from_config(mapping)


def test_unknown_preset_raises_user_input_error():
    with pytest.raises(UserInputError, match="flown"):
        ScanningLaw.preset("wobbly")


@pytest.mark.parametrize("choice", ["flown", "nominal"])
def test_hydra_composes_each_scanning_option(choice):
    # The whole app config, with its typed schema: the YAML keys must match the schema's.
    from hydra import compose, initialize_config_module

    from mcsweep.sweep.schema import register_configs

    register_configs()
    with initialize_config_module(config_module="mcsweep.conf", version_base="1.3"):
        cfg = compose(config_name="config", overrides=[f"scanning={choice}"])
    assert ScanningLaw.from_config(cfg.scanning) == ScanningLaw.preset(choice)
