"""The forked chunk workers' transport (mcsweep.solver.resident): large buffers through shared arenas."""

import numpy as np
import pytest

from mcsweep.solver import resident

pytestmark = pytest.mark.skipif(not resident.fork_available(), reason="no fork start method here")


def _task(item):
    """A chunk task: the chunk's own array plus what the message sent, and a large result."""
    ci, own, state, extra, scale = item
    state["calls"] = state.get("calls", 0) + 1
    return ci, own + scale * extra, state["calls"]


def test_large_arrays_travel_through_the_arenas_unchanged_and_past_a_full_arena_through_the_pipe(monkeypatch):
    rng = np.random.default_rng(3)
    n = 3 * resident.ARENA_MIN_BYTES // 8  # 3 MiB of doubles: each result goes to an arena if it fits
    chunks = [(rng.standard_normal(n), {}) for _ in range(4)]
    taken = []
    original = resident.Arena.take

    def counted(self, at, nbytes):  # called in this process for what the workers send up
        taken.append(nbytes)
        return original(self, at, nbytes)

    monkeypatch.setattr(resident.Arena, "take", counted)
    # two results of 3 MiB per worker and message; an arena of 4 MiB holds one of them
    monkeypatch.setattr(resident, "ARENA_BYTES", 4 * resident.ARENA_MIN_BYTES)
    with resident.forked_chunks(chunks, 2) as run:
        for message in range(3):  # the arenas are reused message after message
            extra = rng.standard_normal(n)  # 3 MiB down to each worker, through its arena
            got = {ci: (out, calls) for ci, out, calls in run(_task, [(ci, extra, 0.5 + message) for ci in range(4)])}
            for ci in range(4):
                np.testing.assert_array_equal(got[ci][0], chunks[ci][0] + (0.5 + message) * extra)
                assert got[ci][1] == message + 1  # each worker keeps its chunks' state
    # per message 2 of the 4 results came up through an arena (the first of each worker), 2 past it
    assert taken.count(n * 8) == 3 * 2
