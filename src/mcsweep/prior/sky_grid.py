"""The sweep's grid of directions, as a sky config gives it: the one check of its keys.

The sweep's config (``sky``, :class:`mcsweep.experiments.f90_sweep.conf.SkyConf`) and a
run's record read back by the prior (``config["sky"]`` of ``provenance.json``,
:class:`mcsweep.prior.means.PriorMeans`) are checked by :func:`check_sky`, so the two
cannot accept different skies.
"""

from __future__ import annotations

from collections.abc import Mapping

from ..errors import UserInputError

__all__ = ["SKY_KINDS", "SKY_FRAMES", "HEALPIX_ORDERS", "check_sky"]

SKY_KINDS = ("healpix", "list")
SKY_FRAMES = ("galactic", "icrs")
HEALPIX_ORDERS = ("nested", "ring")


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def check_sky(sky: Mapping, key: str = "sky") -> dict:
    """The grid of ``sky`` (keys ``kind``, ``nside``, ``order``, ``frame``, ``directions``)
    as ``{"kind", "frame", "nside", "order"}`` (healpix) or ``{"kind", "frame", "directions"}``
    (a list of [lon_deg, lat_deg] pairs in the frame, as floats); anything else a
    :class:`~mcsweep.errors.UserInputError` in one line naming ``key`` (e.g. ``sky.nside=3``).
    """
    def refuse(name, value, accepted):
        raise UserInputError(f"{key}.{name}={value!r} is not accepted; expected {accepted}")

    kind, frame = sky.get("kind"), sky.get("frame", "galactic")
    if kind not in SKY_KINDS:
        refuse("kind", kind, "'healpix' or 'list'")
    if frame not in SKY_FRAMES:
        refuse("frame", frame, "'galactic' or 'icrs'")
    if kind == "healpix":
        nside, order = sky.get("nside"), sky.get("order", "nested")
        if not (isinstance(nside, int) and not isinstance(nside, bool) and nside >= 1 and nside & (nside - 1) == 0):
            refuse("nside", nside, "a power of two >= 1")
        if order not in HEALPIX_ORDERS:
            refuse("order", order, "'nested' or 'ring'")
        return {"kind": kind, "frame": frame, "nside": nside, "order": order}
    directions = list(sky.get("directions") or [])
    if not directions:
        refuse("directions", directions, "a non-empty list of [lon_deg, lat_deg] pairs")
    for d in directions:
        ok = isinstance(d, (list, tuple)) and len(d) == 2 and all(_number(v) for v in d)
        if not (ok and 0.0 <= d[0] <= 360.0 and -90.0 <= d[1] <= 90.0):
            refuse("directions", list(d) if isinstance(d, (list, tuple)) else d,
                   "[lon_deg in 0..360, lat_deg in -90..90] pairs")
    return {"kind": kind, "frame": frame, "directions": [[float(v) for v in d] for d in directions]}
