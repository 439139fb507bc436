"""Tasks on the solver's chunks of a primary solution whose stars stay where the chunks are.

A chunk is ``(blocks, measurements, state)`` (:mod:`mcsweep.solver.executors`); these tasks
take ``(ci, *chunk, *rest)`` and return ``(ci, value)``, as the solver's own
(:mod:`mcsweep.solver.tasks`). They attach a prior to a chunk's stars (its prior sigmas and
inverses, made where the chunk is) and evaluate the solution there with the block functions
of :mod:`~.evaluation`: the same tasks wherever the chunks are, held in this process
(:class:`~mcsweep.solver.executors.HeldChunks`) or on a Dask cluster's workers.
"""

from __future__ import annotations


import numpy as np

from ...astrometry.solve import prior_diagonal
from ...solver.frame import typical_weights, weight_sums
from ...solver.problem import blocks_with_inverses, star_arrays
from ...solver.reduction import pairwise_sum
from ...solver.selection import digit_counts
from .experiment import epoch_offset_yr, prior_sigmas
from .evaluation import block_attitude_sq, block_frame_sums, block_outcome

__all__ = ["attach_prior", "with_stars", "block_slices", "prior_task", "weight_digits", "fit_task", "outcome_task",
           "outcome_slice", "attitude_sq_task"]


def attach_prior(chunk: tuple, arg: tuple) -> tuple:
    """The solver's chunk ``(blocks, measurements, state)`` for one prior, made on its worker:
    each star's prior sigma from its (l, b, G) (``settings.sigma_f90_mas``, the prior
    ``label``) and the stars' arrays of that prior (:func:`~mcsweep.solver.problem.star_arrays`);
    ``arg = (settings, label)`` is all that is sent per prior. With ``kept["border"]`` (each
    block's rows of a calibration's design) the state holds them as the solver's border."""
    blocks, hs, kept = chunk
    settings, label = arg
    sig = prior_sigmas(settings, label, kept["l"], kept["b"], kept["phot_g_mean_mag"])
    stars = star_arrays(blocks, kept["normals"], prior_diagonal(sig, settings.ratio_R))
    stars.update(kept)
    stars["sigma_prior"] = sig
    if settings.evaluation_epoch == "star_mean":
        stars["tau_yr"] = epoch_offset_yr(settings, kept["mean_tcb_jd"])
    state = {"stars": stars}
    if "border" in kept:  # the calibration's columns (mcsweep.solver.solve_global's border)
        state["border"] = kept["border"]
    return blocks_with_inverses(blocks, stars["binv"]), hs, state


def with_stars(chunk: tuple, kept: dict) -> tuple:
    """A chunk ``(blocks, measurements, state)`` sent from the driver, with its stars' arrays
    ``kept`` in place of the state (as :func:`~.blocks.build_chunk` makes it)."""
    return (*chunk[:2], kept)


def block_slices(blocks) -> list:
    first = blocks[0].first
    return [slice(b.first - first, b.first - first + b.n) for b in blocks]


def prior_task(item):
    """What the driver needs of a chunk's stars under a prior: singular blocks and the frame
    weights' sums (fixed tree)."""
    ci, blocks, _, st = item
    S = st["stars"]
    return ci, (int(np.count_nonzero(~S["ok"])), pairwise_sum(weight_sums(S["g_raw"][v]) for v in block_slices(blocks)))


def weight_digits(item):
    """A round of the selection of the medians that set the frame penalty
    (:mod:`mcsweep.solver.selection`): ``queries[w]`` for the stars' weights ``w`` (0 position,
    1 proper motion, :func:`~mcsweep.solver.frame.typical_weights`)."""
    ci, _, _, st, queries = item
    S = st["stars"]
    weights = typical_weights(S["normals"], S["prior"])
    return ci, [digit_counts(weights[w], [q])[0] for w, q in queries]


def fit_task(item):
    """A chunk's part of the frame rotator's fit (:func:`~.evaluation.block_frame_sums`), summed in the fixed tree."""
    ci, blocks, _, st, equal = item
    S = st["stars"]
    dx = st["x"] - S["x_true"]
    return ci, pairwise_sum(block_frame_sums(S["K"][v], S["binv"][v], dx[v], equal) for v in block_slices(blocks))


def outcome_task(item):
    """Each star's outcome, kept in the chunk's state for :func:`outcome_slice`."""
    ci, blocks, _, st, eps, omega, confidence = item
    S = st["stars"]
    dx = st["x"] - S["x_true"]
    tau_yr = S.get("tau_yr")
    parts = [block_outcome(S["K"][v], S["binv"][v], dx[v], eps, omega, None if tau_yr is None else tau_yr[v],
                           confidence)
             for v in block_slices(blocks)]
    st["outcome"] = tuple(np.concatenate([p[i] for p in parts]) for i in range(3))
    return ci, None


def outcome_slice(item):
    """The outcome (inside, position and parallax errors) and prior sigma of the chunk's
    solved stars ``lo:hi`` (solved-star indices of the whole solution)."""
    ci, blocks, _, st, lo, hi = item
    first = blocks[0].first
    a, b = max(lo - first, 0), max(min(hi - first, len(st["stars"]["x_true"])), 0)
    return ci, (*(o[a:b] for o in st["outcome"]), st["stars"]["sigma_prior"][a:b])


def attitude_sq_task(item):
    """A chunk's sum of squared attitude errors (:func:`~.evaluation.block_attitude_sq`)."""
    ci, blocks, _, _, *args = item
    return ci, pairwise_sum(block_attitude_sq(b, *args) for b in blocks)
