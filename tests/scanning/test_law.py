"""ScanningLaw: presets in conf/scanning/, from_config, validation, Hydra composition."""

import dataclasses

import pytest
from omegaconf import OmegaConf

from mcsweep.errors import UserInputError
from mcsweep.scanning import ScanningLaw


# Published design of the scanning law (de Bruijne et al. 2010, EAS Publ. Ser. 45, 331;
# Gaia Collaboration, Prusti et al. 2016, A&A 595, A1, Sect. 5.2): spin period 6 h
# (60 arcsec/s); spin axis at 45 deg from the Sun, precessing about it with a period of
# 63 days, i.e. 5.8 loops a year. The flown law's fitted constants must stay close.
SPIN_PERIOD_H, SPIN_PERIOD_RTOL = 6.0, 1e-3
LOOPS_PER_YEAR, LOOPS_TOL = 5.8, 0.05


@pytest.mark.parametrize("name", ["flown", "nominal"])
def test_law_has_the_published_spin_period_and_precession_rate(name):
    import numpy as np

    from mcsweep.scanning.attitude import attitude_for

    law = ScanningLaw.preset(name)
    assert law.spin_period_days * 24 == pytest.approx(SPIN_PERIOD_H, rel=SPIN_PERIOD_RTOL)
    # Precession loops counted on the integrated attitude (independent of the constants' values),
    # of the last NSL segment (the only one of 'nominal'), over five years.
    part = attitude_for(law).parts[-1]
    t = part.segment.ref_epoch_jd + np.arange(0.0, 5 * 365.25, 0.05)
    nu = np.unwrap(part.lam_nu_omega(t)[1])
    assert (nu[-1] - nu[0]) / (2 * np.pi) / 5 == pytest.approx(LOOPS_PER_YEAR, abs=LOOPS_TOL)


def test_flown_preset_is_the_default_law():
    # The packaged YAML and the dataclass defaults must describe the same law.
    assert ScanningLaw.preset("flown") == ScanningLaw()


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

    from mcsweep.command.schema import register_configs

    register_configs()
    with initialize_config_module(config_module="mcsweep.conf", version_base="1.3"):
        cfg = compose(config_name="config", overrides=[f"scanning={choice}"])
    assert ScanningLaw.from_config(cfg.scanning) == ScanningLaw.preset(choice)
