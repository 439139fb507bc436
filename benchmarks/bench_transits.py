"""Throughput of the FoV-transit search, against performance targets.

Finds the transits of ``--n-directions`` random directions (default 1e6, uniform on the
sky, seeded) over ``--years`` years (default 5) with :func:`mcsweep.scanning.find_transits`
and prints the wall time, star-years per second, transits per star and peak memory.
Target: 1e6 directions x 5 years in <= 120 s wall on 2 cores, peak memory <= 4 GB.

In the same run, the straightforward reference
(:func:`mcsweep.scanning.reference.reference_transits`: attitude sampled every
``--reference-step-s`` seconds, every star tested at every step) is timed on the first
``--reference-directions`` directions over the same interval; the script prints the
speed ratio (star-years per second, fast / reference) and checks that both find the
same transits.

Set-up that happens once per process (NSL integration, ephemeris table, starting the
worker pool; a few seconds) is done before timing and reported separately. Peak memory: ``ru_maxrss`` of this
process and the largest sampled sum of the PSS (Linux; RSS elsewhere) of this process
and its worker processes, sampled every second (needs psutil; skipped without it).

    python benchmarks/bench_transits.py                          # 1e6 directions, 2 jobs
    python benchmarks/bench_transits.py --n-directions 100000    # reduced size
"""

from __future__ import annotations

import argparse
import resource
import sys
import threading
import time

import numpy as np

from mcsweep.scanning import ScanningLaw, find_transits
from mcsweep.scanning.attitude import attitude_for
from mcsweep.scanning.ephemeris import gaia_position_au
from mcsweep.scanning.reference import reference_transits

#: Target wall time for 1e6 directions x 5 years [s] and peak memory [GB].
TARGET_WALL_S = 120.0
TARGET_MEMORY_GB = 4.0
#: Agreement with the reference: transit times [s].
AGREEMENT_TIME_S = 0.1
START_JD = 2457023.5  # 2015-01-01 TCB


class _PeakRss:
    """Samples the summed RSS of this process and its children in a thread."""

    def __init__(self, interval_s: float = 1.0):
        try:
            import psutil
        except ImportError:  # pragma: no cover - optional
            self.psutil = None
            return
        self.psutil = psutil
        self.interval = interval_s
        self.peak = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _sample(self):
        # PSS (proportional set size) where available, so pages shared between the
        # processes (libraries, memory-mapped inputs) are counted once; RSS otherwise.
        me = self.psutil.Process()
        total = 0
        for proc in [me] + me.children(recursive=True):
            try:
                info = proc.memory_full_info()
                total += getattr(info, "pss", info.rss)
            except self.psutil.Error:
                pass
        self.peak = max(self.peak, total)

    def _run(self):
        while not self._stop.is_set():
            self._sample()
            self._stop.wait(self.interval)

    def __enter__(self):
        if self.psutil is not None:
            self._thread.start()
        return self

    def __exit__(self, *exc):
        if self.psutil is not None:
            self._stop.set()
            self._thread.join()
            self._sample()


def random_directions(n: int, seed: int):
    rng = np.random.default_rng(seed)
    return rng.uniform(0.0, 360.0, n), np.degrees(np.arcsin(rng.uniform(-1.0, 1.0, n)))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n-directions", type=float, default=1e6)
    p.add_argument("--years", type=float, default=5.0)
    p.add_argument("--n-jobs", type=int, default=2)
    p.add_argument("--full-precision", action="store_true",
                   help="int64/float64 output instead of compact=True (int32/float32)")
    p.add_argument("--reference-directions", type=int, default=20)
    p.add_argument("--reference-step-s", type=float, default=20.0)
    p.add_argument("--seed", type=int, default=2015)
    args = p.parse_args(argv)
    n = int(args.n_directions)
    start, end = START_JD, START_JD + 365.25 * args.years
    ra, dec = random_directions(n, args.seed)
    law = ScanningLaw()

    t0 = time.perf_counter()
    attitude_for(law)
    gaia_position_au(np.array([start]))
    find_transits(ra[:10], dec[:10], start, end, law=law)
    if args.n_jobs != 1:
        # Start the reusable worker pool; each worker imports the package and builds its
        # observer-ephemeris table once (~2 s). 4000 directions make two parallel blocks.
        warm = min(n, 4000)
        find_transits(ra[:warm], dec[:warm], start, end, law=law, n_jobs=args.n_jobs)
    setup_s = time.perf_counter() - t0

    with _PeakRss() as peak:
        t0 = time.perf_counter()
        df = find_transits(ra, dec, start, end, law=law, n_jobs=args.n_jobs,
                           compact=not args.full_precision)
        wall = time.perf_counter() - t0
    main_peak_gb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e9
    star_years = n * args.years
    rate = star_years / wall
    frame_gb = df.memory_usage(deep=True).sum() / 1e9

    print(f"directions {n:,}  years {args.years:g}  n_jobs {args.n_jobs}  "
          f"compact {not args.full_precision}")
    print(f"set-up (once per process, not timed below): {setup_s:.2f} s")
    print(f"find_transits: {wall:.2f} s wall, {rate:,.0f} star-years/s, "
          f"{len(df) / n:.2f} FoV transits per direction ({len(df):,} rows, frame {frame_gb:.2f} GB)")
    print(f"peak memory: this process {main_peak_gb:.2f} GB"
          + (f", with workers (PSS) {peak.peak / 1e9:.2f} GB" if peak.psutil is not None else ""))
    # Extrapolation: time scales with star-years; memory = what was measured + the output
    # frame scaled up (interpreter, worker processes and buffers do not grow with n).
    scale = 1e6 * 5.0 / star_years
    peak_gb = max(main_peak_gb, peak.peak / 1e9 if peak.psutil is not None else 0.0)
    print(f"extrapolated to 1e6 x 5 yr: ~{wall * scale:.0f} s (target <= {TARGET_WALL_S:.0f} s), "
          f"peak memory ~{peak_gb + frame_gb * (scale - 1):.1f} GB (target <= {TARGET_MEMORY_GB:.0f} GB)")

    m = min(args.reference_directions, n)
    t0 = time.perf_counter()
    ref = reference_transits(ra[:m], dec[:m], start, end, law=law, step_s=args.reference_step_s)
    ref_wall = time.perf_counter() - t0
    ref_rate = m * args.years / ref_wall
    print(f"reference ({m} directions, {args.reference_step_s:g} s steps): {ref_wall:.2f} s, "
          f"{ref_rate:,.1f} star-years/s; speed ratio fast/reference = {rate / ref_rate:,.0f} "
          "(the reference's cost is mostly per time step, shared by its directions, so the "
          "ratio falls as --reference-directions grows)")
    fast = df[df["source_index"] < m]
    same = (len(fast) == len(ref)
            and np.array_equal(fast["source_index"].to_numpy(), ref["source_index"].to_numpy())
            and np.max(np.abs(fast["tcb_jd"].to_numpy() - ref["tcb_jd"].to_numpy()), initial=0.0) * 86400
            < AGREEMENT_TIME_S)
    print(f"agreement with the reference on those directions: {'yes' if same else 'NO'} "
          f"({len(fast)} vs {len(ref)} transits)")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
