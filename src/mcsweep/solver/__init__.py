"""solver stage: the global (primary) astrometric solution, stars and attitude together.

Paper Sect. 4.2 (Table 3): one year of observations, the attitude determined from the
same observations as the stars. The solver follows AGIS (Lindegren et al. 2012, A&A
538, A78) as Bombrun et al. (2012, A&A 538, A77) read it: the normal equations of all
unknowns are solved by conjugate gradients, preconditioned with the block updates of
AGIS in symmetric Gauss-Seidel order (the per-star 5 x 5 source blocks with the Eq. 18
prior, and the banded attitude block with each star's local absorption removed).

Modules
-------
attitude_spline
    Cubic B-spline basis in time for the three small-angle attitude corrections.
observations
    Flat per-observation partial derivatives (source and attitude) of AL/AC measurements.
source_update
    Per-star normal blocks with the prior and their batched solution (the AGIS S block).
attitude_update
    Banded attitude normal matrix in LAPACK storage and its solution (the AGIS A block).
frame
    Orientation and spin (6 dof): the frame constraint and the frame-rotator fit.
blocks
    Fixed blocks of stars in compact storage and the per-block (chunk task) work.
reduction
    Sums over blocks in a fixed pairwise tree: bit-identical for any chunking.
problem
    The normal equations in blocks of stars (GlobalProblem, ResidentProblem) and their chunks.
tasks
    The chunk tasks of the solver's passes (setup, absorption, the sweeps, residuals).
executors
    Running a pass on the chunks and summing its outputs in the fixed tree; lost chunks.
schur_preconditioner
    The banded attitude Schur block of the preconditioner and its Cholesky factor.
stopping
    The stopping rule (the energy criterion) and the per-iteration record.
pcg
    The preconditioned conjugate-gradient iteration (setup pass, one iteration's steps, loop).
solve
    solve_global: the PCG solution on chunks in-process, on forked workers or on Dask.
resident
    Forked chunk workers that keep their blocks (the passes on one machine's cores).
dask_resident
    Chunks kept on the workers of a Dask cluster (the passes beyond one machine).
selection
    Medians and quantiles of values spread over chunks, by selection (the frame penalty).
direct
    The same normal equations by sparse LU (tests' and benchmarks' reference).
calibration
    A basic-angle variation solved with the stars and the attitude (its Schur complement).

Only :mod:`mcsweep.astrometry` and :mod:`mcsweep.scanning` are imported.
"""

from .attitude_spline import AttitudeSpline
from .attitude_update import attitude_band, band_to_dense
from .problem import SOLVER_BLOCK_STARS, GlobalProblem, in_block_order, make_blocks
from .schur_preconditioner import AttitudeNotDetermined
from .solve import solve_global
from .stopping import ConvergenceRecord
from .frame import fit_frame, frame_attitude, frame_offsets, precision_weights
from .observations import Measurements, attitude_partials, build_measurements
from .source_update import solve_sources, source_normals
from ..renamed_names import old_names

__all__ = [
    "AttitudeSpline",
    "Measurements",
    "attitude_partials",
    "build_measurements",
    "source_normals",
    "solve_sources",
    "attitude_band",
    "band_to_dense",
    "fit_frame",
    "frame_offsets",
    "frame_attitude",
    "precision_weights",
    "GlobalProblem",
    "SOLVER_BLOCK_STARS",
    "make_blocks",
    "in_block_order",
    "ConvergenceRecord",
    "solve_global",
    "AttitudeNotDetermined",
]

#: The solver's measurements were "Observations", a word the config group and the few-transit
#: solver's input table also used.
__getattr__ = old_names(__name__, {"Observations": "Measurements", "build_observations": "build_measurements"})
