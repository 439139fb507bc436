# Reference astrometric solutions computed with ESA's gaiasupdate (PyPI 0.1.2, ESA-PL licence).
#
# What it computes
#   For every source in every vendored epoch-astrometry file, gaiasupdate's own DR4-like source
#   update with the AGIS source excess noise taken from the epoch file (no excess-noise fit, fixed
#   weights, observations filtered on used_by_agis_al), i.e.
#       GaiaEpochAstrometryArchive.supdate(df, source_id, model, compute_excess_noise=False)  (snake_case archive data)
#       GaiaEpochAstrometryCu9.supdate(df, source_id, model, compute_excess_noise=False)      (camelCase DPAC/CU9 data)
#   for model '5p_single_source' and '6p_constrained_colour' (Gaussian prior 0.085e-3 on the
#   pseudocolour, colour factors scaled by -1e3 inside gaiasupdate), at gaiasupdate's reference
#   epoch J2017.5 (TCB) = gaiasupdate.constants.DR4_REFERENCE_EPOCH.
#   For the heaviside sample (src/mcsweep/data/epoch_astrometry/sample_epoch_astrometry.parquet)
#   the 5p solution is also computed with the excess noise replaced by AGIS's excessNoise_mas from
#   sample_agis_results.parquet (variant 'agis_excess_noise', as gaiasupdate's
#   tests/test_heaviside_weight.py does).
#
# Output: tests/data/gaiasupdate/reference_solutions.csv, one row per (file, source_id, model, variant).
#   dalpha_star_mas, ddelta_mas: offsets (mas) of the position at J2017.5 w.r.t. the reference position
#   the centroid_pos_al values are relative to; parallax_mas; pmra_mas_yr; pmdec_mas_yr;
#   pseudocolour (6p only, gaiasupdate's units, i.e. 1/nm; empty for 5p); *_error = formal errors
#   (sqrt of the diagonal of the inverse normal matrix). n_obs = number of CCD (AL) observations used.
#   Floats are written with repr() (shortest exact round-trip representation).
#
# How to run, from the repository root, in a separate virtualenv (gaiasupdate pins pandas<3):
#   python3 -m venv /tmp/gsenv && /tmp/gsenv/bin/pip install gaiasupdate==0.1.2
#   /tmp/gsenv/bin/python tests/data/gaiasupdate/make_reference.py
#
# The script is deterministic: fixed file order, sources sorted, no random numbers.

import csv
import logging
import math
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
from astropy.table import Table

import gaiasupdate
from gaiasupdate.constants import DR4_REFERENCE_EPOCH
from gaiasupdate.epoch_astrometry import (EpochAstrometryDataFrameArchive, EpochAstrometryDataFrameCu9,
                                          GaiaEpochAstrometryArchive, GaiaEpochAstrometryCu9)

EXPECTED_GAIASUPDATE_VERSION = '0.1.2'

HERE = Path(__file__).resolve().parent                  # tests/data/gaiasupdate
REPO_ROOT = HERE.parents[2]
SAMPLE_DIR = REPO_ROOT / 'src' / 'mcsweep' / 'data' / 'epoch_astrometry'
OUTPUT = HERE / 'reference_solutions.csv'

MODELS = [('5p', '5p_single_source'), ('6p', '6p_constrained_colour')]

PARAMS = ['dalpha_star_mas', 'ddelta_mas', 'parallax_mas', 'pmra_mas_yr', 'pmdec_mas_yr', 'pseudocolour']
COLUMNS = (['file', 'source_id', 'model', 'variant', 'excess_noise_mas', 'n_obs']
           + PARAMS + [f'{p}_error' for p in PARAMS])

DATALINK_STEM = 'gacs_data_link/EPOCH_ASTROMETRY-Gaia DR4_INT2 1'


def read_datalink_table(path, ext):
    """Read a Gaia-archive DataLink product with astropy and convert it to what gaiasupdate needs.

    Conversions (as in gaiasupdate's tests/test_gacs_interface.py):
    - all formats: Table.read(...).to_pandas(), then GaiaEpochAstrometryArchive.astropy_table_to_df,
      which replaces the numpy MaskedArray cells of the VOTable (.xml, .votplain.xml) array columns
      by their .data (masked elements are NaN there; none of them is a used_by_agis_al observation).
    - csv: nothing else. The header has `used_by_agis_al` twice; astropy renames the second one to
      `used_by_agis_al_1`. Its values are in fact a copy of used_by_agis_al (they do not match the
      all-False used_by_agis_ac of the other formats), and gaiasupdate never reads it
      (archive_to_cu9 keeps only used_by_agis_al), so it is left as is. The array columns are strings
      '(...)' which gaiasupdate itself parses (eval with false/true) when exploding.
    - fits: the boolean array columns are stored as bytes 84 ('T') / 70 ('F'); they are converted to
      boolean arrays (value == 84), otherwise the filter `used_by_agis_al == True` would drop everything.
    - ecsv: nothing else.
    """
    df = Table.read(path).to_pandas()
    df = GaiaEpochAstrometryArchive.astropy_table_to_df(df)
    if ext == 'fits':
        for col in ['used_by_agis_al', 'used_by_agis_ac']:
            df[col] = df[col].apply(lambda x: np.asarray(x) == 84)
    return df


def epoch_files():
    """Yield (relative file name, kind, loader) in a fixed order. kind is 'archive' or 'cu9'."""
    yield ('sample_epoch_astrometry.parquet', 'cu9',
           lambda: pd.read_parquet(SAMPLE_DIR / 'sample_epoch_astrometry.parquet'))
    for ext in ['csv', 'ecsv', 'fits', 'xml', 'votplain.xml']:
        rel = f'{DATALINK_STEM}.{ext}'
        yield (rel, 'archive', lambda rel=rel, ext=ext: read_datalink_table(HERE / rel, ext))
    yield ('gacs_data_link/1_epoch_astrometry.parquet', 'cu9',
           lambda: pd.read_parquet(HERE / 'gacs_data_link' / '1_epoch_astrometry.parquet'))
    # per-CCD arrays stored as strings '(..., false, true, ...)': gaiasupdate parses them itself
    yield ('constrained_colour/1_archive_epoch_astro.parquet', 'archive',
           lambda: pd.read_parquet(HERE / 'constrained_colour' / '1_archive_epoch_astro.parquet'))
    yield ('constrained_colour/2_epoch_astrometry.parquet', 'cu9',
           lambda: pd.read_parquet(HERE / 'constrained_colour' / '2_epoch_astrometry.parquet'))


KIND = {
    'archive': dict(cls=GaiaEpochAstrometryArchive, source_id='source_id', excess_noise='agis_source_excess_noise'),
    'cu9': dict(cls=GaiaEpochAstrometryCu9, source_id='sourceId', excess_noise='agisSourceExcessNoise'),
}


def fmt(x):
    return repr(float(x))


def solve(kind, df, source_id, model):
    """Run gaiasupdate's supdate on a copy of df (supdate modifies some inputs in place)."""
    with warnings.catch_warnings():
        # gaiasupdate scales colourFactorAl in place on a filtered frame (pandas SettingWithCopyWarning)
        warnings.simplefilter('ignore', pd.errors.SettingWithCopyWarning)
        return KIND[kind]['cls'].supdate(df.copy(), source_id, model, compute_excess_noise=False)


def excess_noise_of(kind, df, source_id):
    k = KIND[kind]
    values = pd.unique(df.loc[df[k['source_id']] == source_id, k['excess_noise']])
    if len(values) != 1:
        raise ValueError(f'source {source_id}: excess noise not unique: {values}')
    return float(values[0])


def make_row(rel, source_id, label, variant, excess_noise_mas, result):
    p = np.asarray(result['parameters'], dtype=float)
    e = np.asarray(result['parameters_formal_uncertainty'], dtype=float)
    n_par = 5 if label == '5p' else 6
    if len(p) != n_par or len(e) != n_par:
        raise RuntimeError(f'{rel} {source_id} {label}: got {len(p)} parameters')
    if result['n_outliers'] != 0 or result['n_measurements'] != result['n_data_total']:
        raise RuntimeError(f'{rel} {source_id} {label}: unexpected outliers with fixed weights')
    row = {'file': rel, 'source_id': str(int(source_id)), 'model': label, 'variant': variant,
           'excess_noise_mas': fmt(excess_noise_mas), 'n_obs': str(int(result['n_measurements']))}
    for i, name in enumerate(PARAMS):
        row[name] = fmt(p[i]) if i < n_par else ''
        row[f'{name}_error'] = fmt(e[i]) if i < n_par else ''
    return row


def main():
    logging.basicConfig(level=logging.WARNING)
    if gaiasupdate.__version__ != EXPECTED_GAIASUPDATE_VERSION:
        raise SystemExit(f'expected gaiasupdate {EXPECTED_GAIASUPDATE_VERSION}, found {gaiasupdate.__version__}')
    for accessor in (EpochAstrometryDataFrameArchive, EpochAstrometryDataFrameCu9):
        assert accessor._reference_epoch is DR4_REFERENCE_EPOCH
    assert DR4_REFERENCE_EPOCH.scale == 'tcb' and DR4_REFERENCE_EPOCH.jyear == 2017.5

    agis = pd.read_parquet(SAMPLE_DIR / 'sample_agis_results.parquet')
    agis_excess_noise = agis.set_index('sourceId')['excessNoise_mas'].astype('float64').to_dict()

    rows = []
    for rel, kind, load in epoch_files():
        try:
            df = load()
        except Exception as exc:  # report and skip a format that cannot be read
            print(f'SKIP {rel}: cannot be read ({type(exc).__name__}: {exc})')
            continue
        sid_col = KIND[kind]['source_id']
        source_ids = sorted(int(s) for s in pd.unique(df[sid_col]))
        n_before = len(rows)
        for source_id in source_ids:
            excess = excess_noise_of(kind, df, source_id)
            for label, model in MODELS:
                result = solve(kind, df, source_id, model)
                rows.append(make_row(rel, source_id, label, 'file_excess_noise', excess, result))
            if rel == 'sample_epoch_astrometry.parquet':
                # 5p with AGIS's excess noise: replace the per-transit agisSourceExcessNoise (float32)
                # by AGIS's excessNoise_mas (float64) and run the same supdate path.
                df_agis = df.astype({'agisSourceExcessNoise': 'float64'})
                df_agis['agisSourceExcessNoise'] = df_agis['sourceId'].map(agis_excess_noise).astype('float64')
                excess_agis = agis_excess_noise[source_id]
                result = solve(kind, df_agis, source_id, '5p_single_source')
                rows.append(make_row(rel, source_id, '5p', 'agis_excess_noise', excess_agis, result))
        print(f'{rel}: {len(source_ids)} source(s), {len(rows) - n_before} solution(s)')

    for row in rows:
        for key in COLUMNS[4:]:
            if row[key] != '' and not math.isfinite(float(row[key])):
                raise RuntimeError(f'non-finite {key} in {row["file"]} source {row["source_id"]} {row["model"]}')

    with open(OUTPUT, 'w', newline='') as fh:
        writer = csv.DictWriter(fh, fieldnames=COLUMNS, lineterminator='\n')
        writer.writeheader()
        writer.writerows(rows)
    print(f'wrote {len(rows)} rows to {OUTPUT.relative_to(REPO_ROOT)}')


if __name__ == '__main__':
    main()
