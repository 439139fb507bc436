"""The chunk tasks of the solver's passes: what a worker does with the chunk it keeps.

Each pass of the PCG iteration (:mod:`~mcsweep.solver.pcg`) runs one of these tasks on every
chunk, on the executor that holds it (:mod:`~mcsweep.solver.executors`). Every task's item
starts (chunk index, blocks, measurements, state): what a worker keeps. ``state`` (a dict,
filled by :func:`setup_task`) holds the chunk's share of every star vector of the iteration
(right-hand side, solution, residual, search direction, ``N p``, the preconditioned residual
and the prior-and-frame parts kept for the residual RMS), updated in place, so a pass sends
only attitude-sized vectors and a few numbers and gets the same back (the driver keeps the
attitude vectors and the banded Schur factor). Per-block numbers (dots, sums) are added in
the fixed tree of :mod:`~mcsweep.solver.reduction` and the attitude vectors per leaf of
blocks, so no result depends on the chunking.

The tasks, in the order of a solution:

* :func:`setup_task`: the right-hand side ``b = A'h`` (less what a starting attitude
  explains), the star vectors, and with bordering unknowns their columns ``G = A'C``;
* :func:`absorption_task`: the stars' absorption of the banded Schur block, one slab of its
  columns (:mod:`~mcsweep.solver.schur_preconditioner`);
* per iteration, the three rounds of the symmetric block Gauss-Seidel preconditioner
  (Bombrun et al. 2012, A&A 538, A77, the source and attitude blocks of AGIS, Lindegren et
  al. 2012, A&A 538, A78): :func:`forward_task` (the step, then the first sweep),
  :func:`back_task` (the last sweep and the data part of ``N z``), :func:`direction_task`
  (``N z`` with the prior and the frame penalty, the new search direction and ``q = N p`` by
  recursion);
* :func:`residual_task`: the measurements' residuals of the solution.

The tasks are module-level functions (picklable; an executor names them by ``__name__``).
"""

from __future__ import annotations

import numpy as np

from . import blocks as B
from . import kernel_backend
from .frame import normalised_weights
from .reduction import pairwise_dot, pairwise_sum

__all__ = ["setup_task", "absorption_task", "forward_task", "back_task", "direction_task", "residual_task",
           "add_setup", "add_in_place"]



def _views(blocks, *vectors):
    """Per block, the block's rows of each chunk vector (n_chunk, 5)."""
    first = blocks[0].first
    return [[v[b.first - first:b.first - first + b.n] for v in vectors] for b in blocks]


def _leaf_runs(blocks, leaves):
    """Per leaf (``leaves``: local block ranges), its blocks as (index in the chunk, block, rows of
    a chunk star vector)."""
    first = blocks[0].first
    for lo, hi in leaves:
        yield [(k, b, slice(b.first - first, b.first - first + b.n)) for k, b in enumerate(blocks[lo:hi], lo)]


def add_setup(a: dict, b: dict) -> dict:
    """Two partial sums of the setup pass, added into ``a``'s arrays where they are writable:
    the partials are the tree's own (nobody else holds them), and at AGIS's knots each holds
    attitude vectors of 2.3e6 unknowns, one fewer alive per level. Element by element, so the
    same bits as ``a + b``."""
    return {k: add_in_place(a[k], b[k]) if isinstance(a[k], np.ndarray) else a[k] + b[k] for k in a}


def setup_task(item):
    """Right-hand side and the chunk's star vectors. ``prior, K, g``: the chunk's arrays, or
    (stars kept with the chunk, ``st["stars"]``: :func:`~mcsweep.solver.problem.star_arrays`) None, None and the
    frame weights' means."""
    ci, blocks, hs, st, prior, K, g, leaves, start = item
    b_s = np.empty((sum(b.n for b in blocks), 5))
    stars, cols = st.get("stars"), st.get("border")
    g_s = None if cols is None else np.empty((cols[0].shape[1], len(b_s), 5))
    if prior is None:
        prior, K, g = stars["prior"], stars["K"], normalised_weights(stars["g_raw"], g)

    def leaf_setup(run):
        """The leaf's sums, its blocks' added in block order (streamed, one block's alive at a
        time)."""
        acc = None
        for k, b, v in run:
            part = B.block_setup(b, hs[k], start)  # less what a starting attitude explains (pcg's module notes)
            b_s[v] = part.pop("b_s")
            part["bb"] = pairwise_dot(b_s[v], b_s[v])
            if cols is not None:  # G = A' C, the bordering columns' right-hand sides (pcg's module notes)
                g = B.gather(b)
                for j, col in enumerate(cols[k].T):
                    g_s[j, v] = B.src_adjoint(b, col, g)
                part["g_a"] = np.stack([B.att_adjoint(b, col, g) for col in cols[k].T])
            acc = part if acc is None else add_setup(acc, part)
        return acc

    sums = pairwise_sum((leaf_setup(run) for run in _leaf_runs(blocks, leaves)), add_setup)
    st.clear()
    if stars is not None:
        st["stars"] = stars
    if cols is not None:
        st["border"], st["g_s"] = cols, g_s
    zero = np.zeros_like(b_s)
    st.update(b=b_s, x=zero.copy(), r=b_s.copy(), e_x=zero.copy(), p=zero.copy(), q=zero.copy(), e_p=zero,
              prior=np.ascontiguousarray(prior, dtype=float), K=np.ascontiguousarray(K, dtype=float),
              g=np.ascontiguousarray(g, dtype=float))
    return ci, sums


def absorption_task(item):
    """The chunk's part of the banded Schur block's absorption in the band's unknowns
    ``columns = (lo, hi)`` (one slab, :data:`~mcsweep.solver.schur_preconditioner.SETUP_SLAB_BYTES`):
    its blocks' added per leaf in block order and the leaves in the fixed tree, as
    :func:`setup_task` adds its sums.
    Needs the stars' prior that :func:`setup_task` kept."""
    ci, blocks, _, st, columns, leaves = item
    prior = st["prior"]

    def leaf_absorption(run):
        acc = None
        for _, b, v in run:
            part = B.schur_absorption(b, prior[v], columns=columns)
            acc = part if acc is None else add_in_place(acc, part)
        return acc

    return ci, pairwise_sum((leaf_absorption(run) for run in _leaf_runs(blocks, leaves)), add_in_place)


def add_in_place(a, b):
    """``a + b`` into ``a`` where it is writable (a partial sum of the tree's own)."""
    return np.add(a, b, out=a) if a.flags.writeable else a + b


def forward_task(item):
    """Apply the step ``alpha`` (None: none yet) to x, r and (N_p + F) x; the chunk's shares of
    the convergence numbers; then the first sweep of the preconditioner on the new r."""
    ci, blocks, _, st, alpha, leaves = item
    if alpha is None:
        numbers, largest = np.zeros(4), 0.0
    else:
        step = alpha * st["p"]
        st["x"] += step
        st["e_x"] += alpha * st["e_p"]
        st["r"] -= alpha * st["q"]
        # x'(b + r), x'(N_p + F) x, sum of squared position steps, r'r
        numbers = pairwise_sum(np.array([pairwise_dot(x, b + r), pairwise_dot(x, e), pairwise_dot(d[:, :2], d[:, :2]), pairwise_dot(r, r)])
                               for x, b, r, e, d in _views(blocks, st["x"], st["b"], st["r"], st["e_x"], step))
        largest = float(np.max(np.abs(step), initial=0.0))
    r = st["r"]
    w_a = pairwise_sum(_leaf_sum(lambda b, v, out: B.block_precondition_forward(b, r[v], out), run)
                       for run in _leaf_runs(blocks, leaves))
    return ci, w_a, numbers, largest


def _leaf_sum(add_block, run) -> np.ndarray:
    """A leaf's attitude vector: its blocks added into one vector in block order
    (:mod:`~mcsweep.solver.reduction`, "Leaves"); ``add_block(block, rows, out)``."""
    out = np.zeros((run[0][1].n_coef, 3))
    for _, b, v in run:
        add_block(b, v, out)
    return out


def back_task(item):
    """Last sweep of the preconditioner: z_s and the data part of N z kept; returned the
    attitude part of N z, and the shares of r'z and of the frame sums C z_s."""
    ci, blocks, _, st, z_a, leaves = item
    r = st["r"]
    z, nz = np.empty_like(r), np.empty_like(r)

    def add_block(b, v, out):
        z[v], nz[v], _ = B.block_precondition_back(b, r[v], z_a, out)

    ya = pairwise_sum(_leaf_sum(add_block, run) for run in _leaf_runs(blocks, leaves))
    st["z"], st["nz"] = z, nz
    g_s = st.get("g_s")
    numbers = pairwise_sum(np.r_[pairwise_dot(r, z), kernel_backend.active().frame_sums(K, g, z)]
                           for r, z, K, g in _views(blocks, st["r"], st["z"], st["K"], st["g"]))
    if g_s is not None:  # G_s' z_s, the stars' share of the border's rows of N z
        numbers = np.r_[numbers, [pairwise_sum(pairwise_dot(gs, z) for gs, z in _views(blocks, g_s[j], z))
                                  for j in range(len(g_s))]]
    return ci, ya, numbers


def direction_task(item):
    """N z completed with the prior and the frame penalty (``sums``: C z over all stars), then
    the new search direction ``p = z + beta p`` (``beta`` None: the first, ``p = z``) and
    ``q = N p`` by recursion; returned the share of p'q."""
    ci, blocks, _, st, sums, beta, w, z_c = item
    e_z = st["prior"] * st["z"]
    kernel_backend.active().frame_apply(st["K"], st["g"], sums, w[0], w[1], e_z)
    nz = st.pop("nz") + e_z
    if z_c is not None:  # + G_s z_c: the border's columns of N z
        for j, c in enumerate(z_c):
            nz += c * st["g_s"][j]
    z = st.pop("z")
    if beta is None:
        st["p"], st["q"], st["e_p"] = z, nz, e_z
    else:
        st["p"] = z + beta * st["p"]
        st["q"] = nz + beta * st["q"]
        st["e_p"] = e_z + beta * st["e_p"]
    return ci, pairwise_sum(pairwise_dot(p, q) for p, q in _views(blocks, st["p"], st["q"]))


def residual_task(item):
    """Residuals of the solution; returned the chunk's share of the stars' solution unless it
    stays with the chunk (``send_x`` False: :class:`~mcsweep.solver.problem.ResidentProblem`)."""
    ci, blocks, hs, st, x_a, keep, send_x, x_c = item
    res = [B.block_residuals(b, h, x, x_a) for b, h, (x,) in zip(blocks, hs, _views(blocks, st["x"]))]
    if x_c is not None:
        res = [r - c @ x_c for r, c in zip(res, st["border"])]
    return ci, (res if keep else None), pairwise_sum(pairwise_dot(r, r) for r in res), (st["x"] if send_x else None)
