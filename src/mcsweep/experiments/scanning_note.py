"""The sentence every section of a report adds when its run's scanning law is extrapolated.

A run records :meth:`mcsweep.scanning.law.ScanningLaw.extrapolation_note` in provenance
(``derived.scanning.extrapolated``) when its interval reaches outside the span the law was
fitted to (or the law is the pre-launch nominal one, fitted to no scan history): its
transits, and so every number of the section, rest on scans Gaia may not have made.
"""

from __future__ import annotations

from ..runtime.document import Document

__all__ = ["extrapolation_para"]


def extrapolation_para(doc: Document, prov: dict) -> None:
    """One paragraph when the run's interval reaches outside the scanning law's validity."""
    note = (prov.get("derived", {}).get("scanning") or {}).get("extrapolated")
    if note:
        doc.para(f"Scanning law: {note}.")
