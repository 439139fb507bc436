"""Published parameters of the built-in galaxy model, each with its provenance.

The model follows the Besancon Galaxy Model as described by Robin, Reyle, Derriere &
Picaud (2003, A&A 409, 523; "R03"), the model behind GUMS (Robin et al. 2012, A&A 543,
A100). Tags in the comments say how well each number was checked:
[V] read in the cited paper or table; [C] read in public code or data files that cite
the paper (two independent ones where noted); [M] standard textbook value.

Only numbers live here; the laws that use them are in :mod:`.density`, :mod:`.luminosity`,
:mod:`.extinction` and :mod:`.kinematics`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

__all__ = [
    "Component",
    "COMPONENTS",
    "THIN_DISC",
    "THIN_DISC_GIANTS",
    "thin_disc_giants",
    "thin_disc",
    "YOUNG_DISC_MAX_AGE_GYR",
    "YOUNG_DISC_THICKNESS_FACTOR",
    "POPULATION_LABELS",
    "R0_KPC",
    "Z_SUN_PC",
    "V_CIRC_KMS",
    "SOLAR_PECULIAR_KMS",
    "DISC_CUTOFF_KPC",
    "THICK_DISC",
    "HALO",
    "BULGE",
    "MS_LIFETIME_SUN_GYR",
    "MS_LIFETIME_SLOPE",
    "OLD_METAL_POOR_TURNOFF_MV",
    "GIANT_G_MINUS_V",
    "SUBGIANT_G_MINUS_V",
    "GIANT_MV_MAX",
    "MASS_MIN_MSUN",
    "MULTIPLICITY_FREQUENCY",
    "LOCAL_GIANT_DENSITY_PC3",
    "BOVY_PDMF_NORM",
    "BOVY_PDMF_SLOPE",
    "BOVY_PDMF_MV_MAX",
    "GCNS_SOURCES_WITHIN_100PC",
    "GCNS_MG_LIMIT",
    "GIANT_THICKNESS_FACTOR",
    "GIANT_VELOCITY_FACTOR",
    "THIN_DISC_THICKNESS_FACTOR",
    "MODEL_VERSION",
]

#: Version of the built-in model's parameter set, recorded in every run's provenance
#: (``galaxy_model_version``). Bump it whenever a number below or a default in
#: :data:`.model.DEFAULT_PARAMS` changes. The versions (docs/galaxy_model.md):
#: ``besancon-r03-1`` the first version, R03's components with the Wielen/Allen
#: luminosity function; ``besancon-r03-2`` calibrated to published local densities
#: (local giant density of Bovy 2017; local density scaled to the GCNS, Smart et al.
#: 2021; thin-disc thickness x 1.15 to keep the paper's Table 1 beam); ``besancon-r03-3``
#: giants and main-sequence stars above 1 Msun at the local densities of Bovy (2017) as
#: sources, only the fainter dwarfs scaled to the GCNS, giants in a thinner disc
#: (:data:`GIANT_THICKNESS_FACTOR`); ``besancon-r03-4`` the giants' velocity ellipsoids
#: scaled to their thinner discs (:data:`GIANT_VELOCITY_FACTOR`); ``besancon-r03-5`` the
#: defaults become the Arenou et al. (1992) dust near the Sun and the subgiants (both
#: options of r03-4), which hold the all-sky counts within 8 % of Gaia DR3's own G counts
#: at G = 4-13 (Gaia Collaboration, Vallenari et al. 2023, as quoted in
#: docs/galaxy_model.md); ``besancon-r03-6`` the evolved stars from PARSEC + COLIBRI
#: isochrones of each component's ages and metallicities (:mod:`.evolved`), main-sequence
#: lifetimes from the same isochrones, the Gaia EDR3 extinction law for giants, and the
#: giants' and young disc's thicknesses set against Gaia DR3's G < 10 counts per colour
#: (:data:`GIANT_THICKNESS_FACTOR`, :data:`YOUNG_DISC_THICKNESS_FACTOR`; docs/galaxy_colours.md).
MODEL_VERSION = "besancon-r03-6"

# --- Sun and rotation ------------------------------------------------------------------
#: Galactocentric distance of the Sun, kpc (R03 Sect. 2: 8.5 kpc) [C].
R0_KPC = 8.5
#: Height of the Sun above the Galactic plane, pc (R03: 15 pc) [C].
Z_SUN_PC = 15.0
#: Circular velocity, flat rotation curve, km/s (Besancon model: 226 km/s; the same value
#: is the halo's lag in public Besancon/GUMS model files) [C].
V_CIRC_KMS = 226.0
#: Solar motion relative to the LSR (U toward the Galactic centre, V, W), km/s
#: (Schoenrich, Binney & Dehnen 2010, MNRAS 403, 1829) [V].
SOLAR_PECULIAR_KMS = (11.1, 12.24, 7.25)
#: Outer edge of the thin and thick discs, kpc (R03 Sect. 2.1: disc cut at 14 kpc) [C].
DISC_CUTOFF_KPC = 14.0

# --- stellar evolution used for ages -----------------------------------------------------
#: Main-sequence lifetime t_MS = MS_LIFETIME_SUN_GYR * (m / Msun) ** -MS_LIFETIME_SLOPE
#: (textbook scaling t ~ M/L with L ~ M^3.5; e.g. Carroll & Ostlie, Sect. 13.1) [M].
MS_LIFETIME_SUN_GYR = 10.0
MS_LIFETIME_SLOPE = 2.5
#: Lowest stellar mass, Msun (hydrogen-burning limit) [M].
MASS_MIN_MSUN = 0.08
#: Absolute V magnitude of the main-sequence turn-off of old metal-poor populations
#: (thick disc, halo). Newby et al. (2011, ApJ 743, 187): turn-off stars of eleven halo
#: globular clusters peak at M_g = 4.18 [V]; V = g - 0.59 (g - r) - 0.01 (Jester et al.
#: 2005, AJ 130, 873) [M] at the turn-off colour g - r ~ 0.25 gives M_V ~ 4.0. The solar-
#: metallicity dwarf sequence would put an 11-14 Gyr turn-off at M_V ~ 5-6; metal-poor
#: dwarfs of the same mass are brighter, so their luminosity function is shifted.
OLD_METAL_POOR_TURNOFF_MV = 4.0
#: Luminosity-function bins with M_V <= GIANT_MV_MAX are treated as giants: they hold
#: 4.3e-4 stars/pc^3, close to the local giant density 3.9e-4 pc^-3 of Bovy (2017,
#: MNRAS 470, 1360) [V abstract].
GIANT_MV_MAX = 1.0
#: Local number density of giants, sources/pc^3: "Giants contribute 0.00039+/-0.00001
#: stars/pc^3" (Bovy 2017, MNRAS 470, 1360, abstract [V]), from Gaia DR1 TGAS, whose
#: sources are unresolved systems like Gaia's and GUMS's: used as it stands, neither
#: scaled to the GCNS nor divided by the multiplicity (r03-2 did both and kept only
#: 2.3e-4). Independent check: the Fifth Catalogue of Nearby Stars holds 20 red giants
#: within 25 pc (Golovin et al. 2023, A&A 670, A19, as summarised by ARI Heidelberg [S]),
#: 3.1e-4 +- 0.7e-4 pc^-3. The Wielen/Allen bins with M_V <= GIANT_MV_MAX (4.3e-4) give
#: the shape in M_V.
LOCAL_GIANT_DENSITY_PC3 = 3.9e-4
#: Present-day mass function of main-sequence stars above 1 Msun at the Sun:
#: dn/dM = 0.016 (M/Msun)^-4.7 stars pc^-3 Msun^-1 (Bovy 2017, abstract [V]; TGAS
#: sources). It replaces the Wielen/Allen dwarf bins whose centre is brighter than
#: BOVY_PDMF_MV_MAX (M_V < 4.5, i.e. above 1.03 Msun on the Mamajek sequence), each bin
#: holding the integral of dn/dM over its mass range. At M_V = 4 it gives 19e-4 pc^-3
#: mag^-1, Wielen's unscaled value (19e-4): the bright dwarfs did not need r03-2's
#: GCNS scaling (x 0.75 / 1.27), which came from the M dwarfs.
BOVY_PDMF_NORM = 0.016
BOVY_PDMF_SLOPE = 4.7
BOVY_PDMF_MV_MAX = 4.5
#: Sources within 100 pc with M_G < GCNS_MG_LIMIT: the Gaia Catalogue of Nearby Stars
#: (Gaia Collaboration, Smart et al. 2021, A&A 649, A6) [V abstract] holds 331 312
#: objects, about 9 % of them beyond 100 pc, at least 92 % complete down to M9
#: (M_G ~ 15.5 at 100 pc, G ~ 20.5): 301 500 +- 30 000 sources. The dwarfs fainter than
#: BOVY_PDMF_MV_MAX (the Wielen/Allen bins) are scaled so that the model's sources with
#: M_G < 15.5 within 100 pc equal this number (:mod:`.model`; the scale comes out at
#: 0.59, i.e. 0.75 after the multiplicity correction, as in r03-2).
GCNS_SOURCES_WITHIN_100PC = 331_312 * (1 - 0.09)
GCNS_MG_LIMIT = 15.5
#: Thickness of the giants' discs relative to the dwarfs' of the same age (multiplies
#: the Einasto axis ratios of the giant-only thin-disc components, :data:`THIN_DISC_GIANTS`,
#: which also hold the optional subgiants).
#: Calibrated: with giants at Bovy's local density, the all-sky counts of
#: Tycho-2 at G = 4-10 (validation/published_counts.py) are met only if the giants' density
#: falls off faster with height than R03's age laws give (x 1.0: G = 4-10 counts 1.25-1.6
#: times Tycho-2; x 0.45: within 8 %). The giants' density then halves at |z| = 126 pc
#: (x 1.0: 284 pc). Bovy (2017, abstract [V]) finds sech^2 profiles with scale heights
#: ~150 pc for giants: 126 pc is what sech^2(z / h) with h = 150 pc gives (half density
#: at 0.88 h = 132 pc); with the convention sech^2(z / 2h) it would be 264 pc. The
#: abstract does not say which; the counts decide (docs/galaxy_model.md). User-adjustable as
#: ``population.params.giant_thickness_factor`` (:func:`thin_disc_giants`). With the
#: Arenou et al. (1992) dust the calibration was repeated (validation/thickness_grid.py; the
#: grid's results are in docs/research_notes_moved.md and docs/galaxy_model.md).
#: Since besancon-r03-6 the evolved stars come from isochrones (:mod:`.evolved`), whose
#: luminosity function is fainter than the Wielen/Allen giant bins, and the factor was set
#: again with :data:`YOUNG_DISC_THICKNESS_FACTOR`
#: (:func:`mcsweep.validation.dr3_colours.fit_thicknesses`, grid 0.55-0.70 x 0.55-0.75 with
#: the thin-disc factor at its Table 1 beam rule, 1.156; docs/galaxy_colours.md): the smallest
#: RMS of ln(model / Gaia DR3) over DR3's G = 5-10 counts per BP - RP tercile and |b| band (45
#: counts; 0.114): 0.45 -> 0.65. Check, not fit: the thin-disc
#: giants' density then halves at 276 pc, Bovy's (2017) ~150 pc read as sech^2(z / 2h)
#: (264 pc; 0.45 gave 116 pc), validation/thickness_grid.py.
GIANT_THICKNESS_FACTOR = 0.65
#: Factor on the velocity dispersions (U, V and W) of the giant-only thin-disc components,
#: so that their kinematics match their thinner discs. The thickness of an
#: isothermal disc scales with sigma_W^2 at a given surface density: the self-gravitating
#: isothermal sheet rho = rho0 sech^2(z / z0) has z0 = sigma_W^2 / (pi G Sigma) (Spitzer
#: 1942, ApJ 95, 329; Binney & Tremaine 2008, Sect. 4.10 problems) [M], and a tracer far
#: from the mid-plane of such a sheet falls off as exp(-2 |z| / z0 * sigma_sheet^2 /
#: sigma_W^2), again with scale height ~ sigma_W^2 (near the mid-plane, where the potential
#: is harmonic, a tracer's thickness goes as sigma_W instead: the factor itself, the colder
#: bound). A disc x GIANT_THICKNESS_FACTOR as thick therefore has sigma_W x
#: sqrt(GIANT_THICKNESS_FACTOR) (0.81 at 0.65; 0.67 at r03-5's 0.45). sigma_U and sigma_V are
#: scaled alike, keeping each age bin's ellipsoid shape of R03 Table 2 (sigma_U/sigma_W
#: 2.5-2.8; scaling sigma_W alone would make it 3.7-4.2, unlike any measured disc
#: population, e.g. 2.2 for the thin disc in Bensby et al. 2003 Table 1 [V]).
#: R03's own age bins give eps ~ sigma_W^1.37 (a least-squares fit to the six older bins of
#: the table below), which would mean x 0.73 at 0.65; the sigma^2 rule is the milder of the two.
#: Its effect on the bright stars' proper motions: docs/galaxy_model.md.
GIANT_VELOCITY_FACTOR = GIANT_THICKNESS_FACTOR ** 0.5
#: Default thickness factor of the thin disc (multiplies the seven Einasto axis ratios of
#: R03). Chosen so the paper's Table 1 beam keeps its 458 GUMS stars after the
#: GCNS scaling (r03-3: 470 expected; 1.0 gives 379): the R03 old-disc Einasto
#: laws have an exponential-equivalent scale height of about 250 pc, Juric et al. (2008,
#: ApJ 673, 864) find 300 pc [V]; x 1.15 stays between the two. Kept for besancon-r03-6
#: (beam 455): 1.20 would bring Gaia DR3's all-sky counts at G = 9-13 from 0.88-0.91 x to
#: 0.92-0.94 x but the M dwarfs' e-folding height at |z| = 0.3-1 kpc from 329 pc to 350 pc,
#: 17 % above Juric et al.'s 300 pc (docs/galaxy_colours.md).
THIN_DISC_THICKNESS_FACTOR = 1.15
#: G - V of giants: the dwarf-sequence G - V at BP - RP = 1.19 (K3V row of Mamajek's
#: table [V]); red-clump and red-giant-branch stars have BP - RP ~ 1.1-1.3 [M].
GIANT_G_MINUS_V = -0.31
#: G - V of subgiants (``subgiants=true``): the dwarf-sequence G - V of G5V (Mamajek's
#: table [V], ``data/dwarf_sequence_mamajek.ecsv``). Most of the solar neighbourhood's
#: stars off the dwarf sequence at M_V 1.5-4.5 are G-type: Mamajek's densities of "G stars
#: (all luminosity classes)" 4.8e-3 +- 1.1e-3 against G dwarfs 3.3e-3 +- 0.4e-3 pc^-3, of F
#: stars 2.5e-3 against F dwarfs 2.4e-3 (E. Mamajek, "Star densities in the solar
#: neighbourhood", memo_star_dens.html [S]).
SUBGIANT_G_MINUS_V = -0.16

#: Fraction of stellar systems that are multiple in the 10-pc census ("multiplicity
#: frequency of around 27 %", 540 objects in 339 systems): Reyle et al. (2021, A&A 650,
#: A201) [V abstract]. Gaia and GUMS count an unresolved system as one source ("1.1
#: billion stars (single stars or systems)", Robin et al. 2012), whereas the local
#: luminosity function counts component stars; the model turns stars into sources with
#: 1 / (1 + f) sources per star (each multiple system holding at least two stars),
#: uniformly in magnitude (see :mod:`.model`).
MULTIPLICITY_FREQUENCY = 0.27

POPULATION_LABELS = ("thin_disc", "thick_disc", "halo", "bulge")


@dataclass(frozen=True)
class Component:
    """One stellar component (a thin-disc age bin, the thick disc, the halo or the bulge).

    Attributes
    ----------
    name : str
        Unique name, e.g. ``"thin_disc_3"``.
    label : str
        Population label written to the catalogue (one of :data:`POPULATION_LABELS`).
    law : str
        Density law: ``"einasto_young"``, ``"einasto"``, ``"thick"``, ``"halo"`` or
        ``"bulge"`` (see :mod:`.density`).
    rho_ref : float
        Mass density at the reference point, Msun/pc^3 (the Sun; the Galactic centre for
        the bulge).
    age_gyr : tuple of float
        Age range (min, max) in Gyr; a single age has min == max.
    imf : tuple of (float, float) pairs
        Broken power-law IMF dN/dm ~ m^-alpha as ((m_break, alpha_below), ..., (inf, alpha))
        with breaks in Msun.
    sigma_uvw : tuple of float
        Velocity dispersions (U radial, V azimuthal, W vertical), km/s.
    eps : float
        Axis ratio of the disc Einasto law (thin disc) or of the halo.
    metal_poor : bool
        Whether the luminosity function is shifted to the metal-poor turn-off
        (:data:`OLD_METAL_POOR_TURNOFF_MV`).
    lag_kms : float or None
        Mean lag behind circular rotation, km/s; ``None`` computes the asymmetric drift
        from the Jeans equation (thin disc).
    rotates : bool
        False for components without net rotation (lag = circular velocity).
    lf_part : str
        Which part of the local luminosity function the component holds: ``"all"``,
        ``"dwarfs"`` (the thin-disc age bins) or ``"giants"`` (their giant-only
        companions, :data:`THIN_DISC_GIANTS`).
    feh : tuple of float
        Metallicity distribution (mean, standard deviation) in dex, which the isochrones of
        its evolved stars are weighted by (:mod:`.evolved`).
    """

    name: str
    label: str
    law: str
    rho_ref: float
    age_gyr: tuple
    imf: tuple
    sigma_uvw: tuple
    eps: float = 1.0
    metal_poor: bool = False
    lag_kms: float | None = None
    rotates: bool = True
    lf_part: str = "all"
    feh: tuple = (0.0, 0.0)


# IMFs of R03 Table 1 [C: public GUMS/Besancon model files agree]:
# thin disc dN/dm ~ m^-1.6 below 1 Msun, m^-3.0 above; thick disc and halo m^-0.5;
# bulge m^-2.35.
_IMF_THIN = ((1.0, 1.6), (float("inf"), 3.0))
_IMF_OLD = ((float("inf"), 0.5),)
_IMF_BULGE = ((float("inf"), 2.35),)

# Thin disc, seven age bins (R03 Tables 2 and 4) [C, two independent public codes]:
# age range (Gyr), local mass density (Msun/pc^3), Einasto axis ratio eps,
# velocity dispersions (U, V, W) in km/s, and [Fe/H] (mean, dispersion) in dex (R03 Table 1
# [C]). One public file gives sigma_V = 13.7 for the 3-5 Gyr bin; every other bin has
# sigma_V / sigma_U = 0.645, so 23.7 is adopted.
_THIN = (
    ((0.0, 0.15), 4.0e-3, 0.0140, (16.7, 10.8, 6.0), (0.01, 0.12)),
    ((0.15, 1.0), 7.9e-3, 0.0268, (19.8, 12.8, 8.0), (0.03, 0.12)),
    ((1.0, 2.0), 6.2e-3, 0.0375, (27.2, 17.6, 10.0), (0.03, 0.10)),
    ((2.0, 3.0), 4.0e-3, 0.0551, (30.2, 19.5, 13.2), (0.01, 0.11)),
    ((3.0, 5.0), 5.8e-3, 0.0696, (36.7, 23.7, 15.8), (-0.07, 0.18)),
    ((5.0, 7.0), 4.9e-3, 0.0785, (43.1, 27.8, 17.4), (-0.14, 0.17)),
    ((7.0, 10.0), 6.6e-3, 0.0791, (43.1, 27.8, 17.5), (-0.37, 0.20)),
)
#: Upper age (Gyr) of the thin-disc age bins that form the young disc, whose thickness
#: :data:`YOUNG_DISC_THICKNESS_FACTOR` scales: bins 1-3 (0-2 Gyr), the only ones that hold
#: main-sequence stars above 1.66 Msun (the isochrones' turn-off at 2 Gyr,
#: :func:`.evolved.turnoff_mass`): B, A and early-F dwarfs.
YOUNG_DISC_MAX_AGE_GYR = 2.0
#: Factor on the young disc's axis ratios (on top of ``thin_disc_scale_height_factor``);
#: its velocity dispersions go with the square root (the rule of
#: :data:`GIANT_VELOCITY_FACTOR`). Set with :data:`GIANT_THICKNESS_FACTOR` against Gaia
#: DR3's G = 5-10 counts per BP - RP tercile and |b| band (there): 1.0 (no such factor) before
#: besancon-r03-6, 0.65 since. With 1.0 the model holds 1.2-1.45 times DR3's bluest tercile at
#: every G and |b| (B, A and early-F dwarfs). Check, not fit: the A dwarfs' density then
#: halves at 91 pc, Bovy's (2017) ~50 pc for A stars read as sech^2(z / 2h) (88 pc; 1.0 gave
#: 177 pc), :func:`mcsweep.validation.thickness_grid.a_star_half_height_pc`.
YOUNG_DISC_THICKNESS_FACTOR = 0.65
THIN_DISC = tuple(
    Component(
        name=f"thin_disc_{i + 1}", label="thin_disc",
        law="einasto_young" if i == 0 else "einasto",
        rho_ref=rho, age_gyr=age, imf=_IMF_THIN, sigma_uvw=sig, eps=eps, lf_part="dwarfs",
        feh=feh,
    )
    for i, (age, rho, eps, sig, feh) in enumerate(_THIN)
)
#: The giants of each thin-disc age bin, a component of their own: same age, mass
#: density (which sets their share of the local giants) and IMF, but axis ratio
#: x GIANT_THICKNESS_FACTOR and velocity dispersions x GIANT_VELOCITY_FACTOR.


def _thinner(comp, factor):
    """``comp`` with its axis ratio x ``factor`` and its velocity dispersions x sqrt(``factor``)
    (the isothermal-disc rule of :data:`GIANT_VELOCITY_FACTOR`)."""
    v = float(factor) ** 0.5
    return replace(comp, eps=comp.eps * float(factor), sigma_uvw=tuple(s * v for s in comp.sigma_uvw))


def thin_disc(young_factor=YOUNG_DISC_THICKNESS_FACTOR):
    """The thin disc's age bins (:data:`THIN_DISC`) with the young disc's (the bins younger
    than :data:`YOUNG_DISC_MAX_AGE_GYR`) axis ratios x ``young_factor`` and velocity
    dispersions x sqrt(``young_factor``)."""
    return tuple(_thinner(c, young_factor) if c.age_gyr[1] <= YOUNG_DISC_MAX_AGE_GYR else c
                 for c in THIN_DISC)


def thin_disc_giants(thickness_factor=GIANT_THICKNESS_FACTOR, young_factor=1.0):
    """The giant-only thin-disc components for a given giants' thickness factor.

    Axis ratios x ``thickness_factor``, velocity dispersions x sqrt(``thickness_factor``)
    (the isothermal-disc rule of :data:`GIANT_VELOCITY_FACTOR`); everything else as the
    dwarfs' age bin of :func:`thin_disc` (``young_factor``).
    """
    return tuple(replace(_thinner(c, thickness_factor), name=f"{c.name}_giants", lf_part="giants")
                 for c in thin_disc(young_factor))


THIN_DISC_GIANTS = thin_disc_giants(GIANT_THICKNESS_FACTOR, YOUNG_DISC_THICKNESS_FACTOR)

#: Thick disc (R03 Tables 1-4) [C]: 1.34e-3 Msun/pc^3, 11 Gyr, [Fe/H] -0.78 +- 0.30,
#: sigma (67, 51, 42) km/s. Lag 46 km/s behind the LSR: Bensby et al. (2003, A&A 410, 527)
#: Table 1 [V].
#: (Public GUMS model files give 1.64e-3, hR 4 kpc, hz 1.2 kpc instead [C, unverified].)
THICK_DISC = Component(
    name="thick_disc", label="thick_disc", law="thick", rho_ref=1.34e-3,
    age_gyr=(11.0, 11.0), imf=_IMF_OLD, sigma_uvw=(67.0, 51.0, 42.0),
    metal_poor=True, lag_kms=46.0, feh=(-0.78, 0.30),
)
#: Thick-disc shape (R03 Table 3) [C]: scale length 2.5 kpc, scale height 0.8 kpc,
#: parabolic below 0.4 kpc.
THICK_DISC_HR_KPC = 2.5
THICK_DISC_HZ_KPC = 0.8
THICK_DISC_XL_KPC = 0.4

#: Stellar halo (R03 Tables 1-4) [C, two codes]: 9.32e-6 Msun/pc^3, axis ratio 0.76,
#: power law a^-2.44 with a core of 0.5 kpc, 14 Gyr, [Fe/H] -1.78 +- 0.50,
#: sigma (131, 106, 85) km/s, no net rotation (lag = V_CIRC_KMS).
HALO = Component(
    name="halo", label="halo", law="halo", rho_ref=9.32e-6, age_gyr=(14.0, 14.0),
    imf=_IMF_OLD, sigma_uvw=(131.0, 106.0, 85.0), eps=0.76, metal_poor=True,
    rotates=False, feh=(-1.78, 0.50),
)
HALO_POWER = 2.44
HALO_CORE_KPC = 0.5

#: Bulge/bar, Dwek et al. (1995) G2 law as fitted by R03 Table 5 [C, two codes]:
#: central density 13.70 stars/pc^3, scale lengths x0 = 1.59, y0 = z0 = 0.424 kpc,
#: cut-off radius 2.54 kpc, major axis at 90 - 78.9 = 11.1 deg from the Sun-centre line
#: (tilt 3.6 and roll 91.3 deg neglected); 10 Gyr, [Fe/H] 0.0 +- 0.4 (R03 Table 1 [C]);
#: sigma (113, 115, 100) km/s.
#: The central density counts stars; it is turned into a mass density with the mean
#: stellar mass of the bulge IMF (see :mod:`.luminosity`). Bar rotation is neglected.
BULGE_N0_PER_PC3 = 13.70
BULGE_X0_KPC = 1.59
BULGE_Y0_KPC = 0.424
BULGE_Z0_KPC = 0.424
BULGE_RC_KPC = 2.54
BULGE_ANGLE_DEG = 11.1
#: Width of the Gaussian taper beyond the cut-off radius, kpc (R03 Table 3 form) [C].
BULGE_TAPER_KPC = 0.5
BULGE = Component(
    name="bulge", label="bulge", law="bulge", rho_ref=float("nan"), age_gyr=(10.0, 10.0),
    imf=_IMF_BULGE, sigma_uvw=(113.0, 115.0, 100.0), rotates=False, feh=(0.0, 0.4),
)

#: Einasto scale radii (R03 Table 3) [C]: youngest bin h+ = 5.0, h- = 3.0 kpc;
#: older bins h+ = 2.53, h- = 1.32 kpc.
EINASTO_YOUNG_H_KPC = (5.0, 3.0)
EINASTO_OLD_H_KPC = (2.53, 1.32)

#: The default model's components: the thin disc at the default young-disc thickness, its
#: giants' companions, the thick disc, the halo and the bulge.
COMPONENTS = thin_disc() + THIN_DISC_GIANTS + (THICK_DISC, HALO, BULGE)
