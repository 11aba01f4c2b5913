"""Spectral and chromatic parts of the eye: V(λ), LCA and Stiles–Crawford ρ(λ).

Tables are read on the host once (colour-science is numpy-only and is not traced) and
returned as arrays, so wavelengths are data known before tracing.
"""

from __future__ import annotations

import csv
import warnings
from functools import lru_cache
from importlib import resources

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.base.types import as_real_array
from lfjax.model.options import ModelOptions, ModelParameters, model_numbers

LEF_NAME = "CIE 2008 2 Degree Physiologically Relevant LEF"


@lru_cache(maxsize=1)
def lef_data() -> tuple[np.ndarray, np.ndarray]:
    """The CIE 2008 2° physiologically relevant LEF as tabulated: (wavelengths nm, V(λ)),
    colour-science's 1 nm table (read once)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message='.*"Matplotlib" related API')
        import colour

    sd = colour.colorimetry.SDS_LEFS_PHOTOPIC[LEF_NAME]
    return np.asarray(sd.wavelengths, float), np.asarray(sd.values, float)


def lef_range_nm() -> tuple[float, float]:
    """Wavelength range (nm) of the CIE 2008 physiologically relevant LEF data."""
    wl, _ = lef_data()
    return float(wl[0]), float(wl[-1])


def _check_range(name: str, wavelengths_nm: np.ndarray, lo: float, hi: float, what: str):
    bad = (wavelengths_nm < lo) | (wavelengths_nm > hi) | ~np.isfinite(wavelengths_nm)
    if np.any(bad):
        raise ParameterError(name, "{%s} must lie in {lo:g}–{hi:g} nm ({what}); got {got}" % name,
                             lo=lo, hi=hi, what=what, got=wavelengths_nm[bad].tolist())


def luminous_efficiency(wavelengths_nm) -> np.ndarray:
    """Photopic luminous efficiency V(λ) (CIE 2008 2° physiologically relevant LEF).

    Linear interpolation of colour-science's 1 nm table; peak ≈ 1 at 555–556 nm.

    References: Stockman & Sharpe (2000); CIE 170-1:2006 / Sharpe et al. (2005, 2011).
    """
    wavelengths_nm = np.atleast_1d(np.asarray(wavelengths_nm, float))
    wl, values = lef_data()
    _check_range("wavelengths_nm", wavelengths_nm, wl[0], wl[-1], "CIE 2008 LEF data")
    return np.interp(wavelengths_nm, wl, values)


def lca_dioptres(wavelengths_nm, options: ModelOptions | ModelParameters = ModelOptions()):
    """Longitudinal chromatic aberration in dioptres (positive: more power, myopic).

    .. math:: D(λ) = A\\left(\\frac{1}{λ - c} - \\frac{1}{λ_{ref} - c}\\right)

    Thibos et al. (1992) "chromatic eye", constants from ``options`` (paper: A = 633.26,
    c = 214.10 nm, λ_ref = 550 nm). Works on numpy or jax arrays; with
    :class:`~lfjax.model.options.ModelParameters` the constants may be traced (``jax.grad`` in A).
    """
    return options.lca_A * (
        1.0 / (wavelengths_nm - options.lca_c_nm)
        - 1.0 / (options.lca_reference_nm - options.lca_c_nm)
    )


@lru_cache(maxsize=None)
def sce_rho_data(column: str) -> tuple[np.ndarray, np.ndarray]:
    """The Stiles–Crawford ρ(λ) table ``column`` (a ``ModelOptions.sce_table`` name) as
    tabulated: (wavelengths nm, ρ mm⁻²), read once from ``lfjax/data``."""
    text = resources.files("lfjax").joinpath("data/stiles_crawford_rho.csv").read_text()
    rows = list(csv.DictReader(text.splitlines()))
    wl = np.array([float(r["wavelength_nm"]) for r in rows])
    rho = np.array([float(r[column]) for r in rows])
    return wl, rho


def sce_rho_per_mm2(wavelengths_nm, table: str = "isetbio_berendschot_data") -> np.ndarray:
    """Stiles–Crawford peakedness ρ(λ) in mm⁻² (Berendschot et al. 2001, ISETBio table).

    Linear interpolation within the table's 400–700 nm; outside it is an error (ISETBio
    clamps below and returns NaN above).
    """
    wavelengths_nm = np.atleast_1d(np.asarray(wavelengths_nm, float))
    wl, rho = sce_rho_data(table)
    _check_range("wavelengths_nm", wavelengths_nm, wl[0], wl[-1], "Stiles–Crawford ρ(λ) table")
    return np.interp(wavelengths_nm, wl, rho)


def computed_range_nm(options: ModelOptions = ModelOptions()) -> tuple[float, float]:
    """Wavelength range (nm) the model can compute: the LEF data (390–830 nm), narrowed to
    the Stiles–Crawford ρ(λ) table (400–700 nm) unless ``options.sce == "off"``. The one
    statement of that range: every spectrum (:func:`make_spectrum`) is refused outside it."""
    lo, hi = lef_range_nm()
    if options.sce != "off":
        wl, _ = sce_rho_data(options.sce_table)
        lo, hi = max(lo, float(wl[0])), min(hi, float(wl[-1]))
    return lo, hi


def check_computed_range(wavelengths_nm, options: ModelOptions = ModelOptions()) -> None:
    """Wavelengths (nm) inside :func:`computed_range_nm`; a
    :class:`~lfjax.base.errors.ParameterError` naming ``wavelengths_nm``, the range and why
    otherwise (host; before the luminous-efficiency data are loaded)."""
    lo, hi = computed_range_nm(options)
    why = "the LEF data" if options.sce == "off" else (
        f"the Stiles–Crawford ρ(λ) table, read while ModelOptions.sce is {options.sce!r}; "
        "with sce='off' the LEF data's range applies")
    _check_range("wavelengths_nm", np.atleast_1d(np.asarray(wavelengths_nm, float)), lo, hi, why)


class Spectrum(eqx.Module):
    """Sampled spectrum with the chromatic properties of the eye at each wavelength.

    Attributes (shape ``(n_wavelengths,)`` unless stated)
    ----------
    wavelengths_nm : wavelengths, nm.
    weights : spectral weights, V(λ)·Δλ normalised to sum 1 (unitless).
    lca_D : LCA defocus at each wavelength, dioptres.
    sce_rho_per_mm2 : Stiles–Crawford ρ(λ), mm⁻² (0 when SCE is off).
    unit_sum : () 0 or 1: 1 scales each wavelength's PSF (all views) to unit volume before
        weighting (``ModelOptions.wavelength_normalisation="unit_sum"``, ISETBio's
        convention); 0 keeps the energy its apodised pupil transmits (default). Data, not
        a code path, so switching it does not recompile.
    """

    wavelengths_nm: jnp.ndarray = eqx.field(converter=as_real_array)
    weights: jnp.ndarray = eqx.field(converter=as_real_array)
    lca_D: jnp.ndarray = eqx.field(converter=as_real_array)
    sce_rho_per_mm2: jnp.ndarray = eqx.field(converter=as_real_array)
    unit_sum: jnp.ndarray = eqx.field(converter=as_real_array, default=0.0)

    def __check_init__(self):
        shape = self.wavelengths_nm.shape
        for name in ("weights", "lca_D", "sce_rho_per_mm2"):
            if getattr(self, name).shape != shape:
                raise ValueError(
                    f"Spectrum.{name} must have the shape of wavelengths_nm {shape}, "
                    f"got {getattr(self, name).shape}"
                )

    @property
    def n_wavelengths(self) -> int:
        return int(self.wavelengths_nm.shape[0])

    def band(self, start: int, stop: int) -> Spectrum:
        """The wavelengths ``start:stop`` (weights not renormalised)."""
        return Spectrum(self.wavelengths_nm[start:stop], self.weights[start:stop],
                        self.lca_D[start:stop], self.sce_rho_per_mm2[start:stop], self.unit_sum)


def make_spectrum(
    wavelengths_nm=None, options: ModelOptions = ModelOptions(), weights=None,
    parameters: ModelParameters | None = None,
) -> Spectrum:
    """Spectrum for ``wavelengths_nm`` (default 400–700 nm in 10 nm steps).

    Parameters
    ----------
    wavelengths_nm : array_like, nm
        Strictly increasing wavelengths inside the range the model computes
        (:func:`computed_range_nm`: narrower with the Stiles–Crawford effect on).
    options : ModelOptions
        LCA constants, SCE form and table.
    weights : array_like, optional
        Spectral weights; default V(λ) times the trapezoid width of each sample. Normalised
        to sum 1.
    parameters : ModelParameters, optional
        The numeric model to use instead of ``options``' numbers (LCA constants, SCE
        exponent and ρ scale, normalisation blend); may be traced, so ``jax.grad`` and
        ``jax.vmap`` reach them (:func:`model_spectrum`). ``options`` still picks the ρ(λ)
        table and whether it is read at all (``sce="off"``).
    """
    if wavelengths_nm is None:
        wavelengths_nm = np.arange(400.0, 701.0, 10.0)
    wl = np.atleast_1d(np.asarray(wavelengths_nm, float))
    if wl.ndim != 1 or wl.size < 1:
        raise ParameterError("wavelengths_nm", "{wavelengths_nm} must be a 1-D array of >= 1 values, "
                             "got shape {shape}", shape=wl.shape)
    if wl.size > 1 and np.any(np.diff(wl) <= 0):
        raise ParameterError("wavelengths_nm", "{wavelengths_nm} must be strictly increasing, got {got}",
                             got=wl.tolist())
    check_computed_range(wl, options)
    v = luminous_efficiency(wl)
    if weights is None:
        if wl.size == 1:
            widths = np.ones(1)
        else:
            edges = np.concatenate([[wl[0]], 0.5 * (wl[1:] + wl[:-1]), [wl[-1]]])
            widths = np.diff(edges)
            # Uniform grids: equal weights for every sample (rectangle rule, as ISETBio sums).
            if np.allclose(np.diff(wl), wl[1] - wl[0]):
                widths = np.full(wl.size, wl[1] - wl[0])
        w = v * widths
    else:
        w = np.asarray(weights, float)
        if w.shape != wl.shape or np.any(w < 0) or not np.all(np.isfinite(w)):
            raise ValueError("weights must be finite, non-negative and match wavelengths_nm")
    if w.sum() <= 0:
        raise ValueError("spectral weights sum to zero")
    w = w / w.sum()
    rho_table = sce_rho_table(wl, options)
    if parameters is not None:
        return model_spectrum(wl, w, rho_table, parameters)
    # Concrete constants: computed on the host in float64, as the pipeline has always had them.
    n = model_numbers(options)
    return Spectrum(
        wavelengths_nm=jnp.asarray(wl),
        weights=jnp.asarray(w),
        lca_D=jnp.asarray(lca_dioptres(wl, n)),
        sce_rho_per_mm2=jnp.asarray(rho_table * (n.sce_exponent * n.sce_rho_scale)),
        unit_sum=n.unit_sum,
    )


GAUSS_MAX_NODES = 40
"""Most nodes :func:`gauss_rule` builds (the sweep plans at most 16; beyond ~40 the discrete
measure's 1 nm pieces, not the rule, would limit what it resolves)."""


def _gauss_weight_pieces(start_nm: float, stop_nm: float, source):
    """Breakpoints (nm) of ρ(λ) = V(λ)·S(λ) on [start, stop] — every table point of V and of
    the source inside the interval — and ρ as a callable (numpy, nm → unnormalised)."""
    wl_v, v = lef_data()
    points = [wl_v]
    if source is None:
        def rho(x):
            return np.interp(x, wl_v, v)
    else:
        src_wl, src = source
        points.append(src_wl)

        def rho(x):
            return np.interp(x, wl_v, v) * np.interp(x, src_wl, src)
    inner = np.concatenate(points)
    inner = inner[(inner > start_nm) & (inner < stop_nm)]
    edges = np.unique(np.concatenate([[start_nm, stop_nm], inner]))
    return edges, rho


def gauss_rule(n_nodes: int, start_nm: float = 400.0, stop_nm: float = 700.0,
               source=None) -> tuple[np.ndarray, np.ndarray]:
    """The ``n_nodes``-point Gauss rule for the weight ρ(λ) = V(λ)·S(λ) on [start, stop] nm.

    Returns ``(nodes_nm, weights)``, each (n_nodes,): increasing nodes strictly inside the
    interval and positive weights summing to 1, such that Σ wᵢ p(λᵢ) = ∫ p ρ dλ / ∫ ρ dλ for
    every polynomial p of degree ≤ 2·n_nodes − 1 (to float64 rounding). V(λ) is
    :func:`luminous_efficiency` (the CIE 2008 LEF, linear between its 1 nm samples); S is
    the source's relative spectral power, 1 (equal-energy white) or ``source`` =
    (wavelengths nm, power) tabulated, linear between its samples and covering the interval.

    How: ρ is piecewise linear × piecewise linear, so between consecutive table points
    (of V or S) it is a polynomial of degree ≤ 2, and p·ρ of degree ≤ 2n + 1. Gauss–Legendre
    with n + 1 points on each piece therefore integrates it exactly: the discrete measure
    μ = Σⱼ mⱼ δ(λ − xⱼ) (the pieces' Legendre points xⱼ, masses mⱼ = Legendre weight ×
    ρ(xⱼ) × half the piece) has exactly ρ's moments up to degree 2n + 1. The three-term
    recurrence of μ's orthogonal polynomials (Stieltjes' procedure, carried out as Lanczos
    on diag(x) from √m, fully re-orthogonalised, in t = (2λ − start − stop)/(stop − start)
    ∈ [−1, 1] for conditioning) gives the n × n Jacobi matrix; its eigenvalues are the nodes
    and the squared first components of its eigenvectors the weights (Golub & Welsch 1969;
    Gautschi 2004, §2.2 "discretized Stieltjes procedure", exact here because the
    discretisation is).
    """
    if isinstance(n_nodes, bool) or not isinstance(n_nodes, (int, np.integer)) \
            or not (1 <= n_nodes <= GAUSS_MAX_NODES):
        raise ParameterError("n_nodes", "{n_nodes} must be an integer in 1–{hi}, got {got!r}",
                             hi=GAUSS_MAX_NODES, got=n_nodes)
    lo, hi = lef_range_nm()
    start_nm, stop_nm = float(start_nm), float(stop_nm)
    if not (lo <= start_nm < stop_nm <= hi):
        raise ParameterError("start_nm", "{start_nm} < {stop_nm} must lie in {lo:g}–{hi:g} nm "
                             "(CIE 2008 LEF data); got {a:g}, {b:g}", lo=lo, hi=hi,
                             a=start_nm, b=stop_nm)
    if source is not None:
        src_wl, src = (np.asarray(x, float).reshape(-1) for x in source)
        if (src_wl.shape != src.shape or src_wl.size < 2 or np.any(np.diff(src_wl) <= 0)
                or np.any(src < 0) or not np.all(np.isfinite(src))
                or src_wl[0] > start_nm or src_wl[-1] < stop_nm):
            raise ParameterError(
                "source", "{source} must be (wavelengths nm, power): increasing wavelengths "
                "covering {a:g}–{b:g} nm and finite non-negative power of the same length",
                a=start_nm, b=stop_nm)
        source = (src_wl, src)
    n = int(n_nodes)
    edges, rho = _gauss_weight_pieces(start_nm, stop_nm, source)
    x_leg, w_leg = np.polynomial.legendre.leggauss(n + 1)
    half = 0.5 * np.diff(edges)
    mid = 0.5 * (edges[1:] + edges[:-1])
    x = (mid[:, None] + half[:, None] * x_leg[None, :]).reshape(-1)  # nm
    mass = (half[:, None] * w_leg[None, :]).reshape(-1) * rho(x)
    if not np.sum(mass) > 0:
        raise ParameterError("source", "V(λ)·{source} vanishes on {a:g}–{b:g} nm",
                             a=start_nm, b=stop_nm)
    t = (2.0 * x - start_nm - stop_nm) / (stop_nm - start_nm)
    q = np.sqrt(mass / np.sum(mass))
    basis, alpha, beta = [q], [], []
    for k in range(n):
        v = t * basis[-1]
        alpha.append(float(basis[-1] @ v))
        for _ in range(2):  # re-orthogonalise twice against every earlier vector ("twice is enough")
            for b in basis:
                v -= (b @ v) * b
        if k < n - 1:
            beta.append(float(np.linalg.norm(v)))
            basis.append(v / beta[-1])
    jacobi = np.diag(alpha) + np.diag(beta, 1) + np.diag(beta, -1)
    nodes_t, vectors = np.linalg.eigh(jacobi)
    weights = vectors[0] ** 2
    nodes = 0.5 * (start_nm + stop_nm) + 0.5 * (stop_nm - start_nm) * nodes_t
    return nodes, weights / weights.sum()


def gauss_spectrum(n_nodes: int, start_nm: float = 400.0, stop_nm: float = 700.0,
                   options: ModelOptions = ModelOptions(), source=None,
                   parameters: ModelParameters | None = None) -> Spectrum:
    """Spectrum on the ``n_nodes``-point Gauss rule for V(λ)·S(λ) on [start, stop] nm
    (:func:`gauss_rule`): its nodes as the wavelengths, its weights as the spectral
    weights, LCA and SCE of ``options`` (or ``parameters``) as :func:`make_spectrum` gives
    them. The pipeline's Σ_λ w_λ OTF_λ is then the Gauss quadrature of ∫ V S OTF dλ / ∫ V S
    dλ: exact for an OTF polynomial of degree ≤ 2n − 1 in λ, where the uniform grid's
    rectangle rule spends samples at the ends of the range, which V(λ) hardly weighs."""
    nodes, weights = gauss_rule(n_nodes, start_nm, stop_nm, source)
    return make_spectrum(nodes, options, weights=weights, parameters=parameters)


def sce_rho_table(wavelengths_nm, options: ModelOptions = ModelOptions()) -> np.ndarray:
    """ρ(λ) of ``options.sce_table`` at ``wavelengths_nm``, mm⁻² (host); zeros when
    ``options.sce == "off"`` (the table, 400–700 nm, is then not read)."""
    wl = np.atleast_1d(np.asarray(wavelengths_nm, float))
    if options.sce == "off":
        return np.zeros_like(wl)
    return sce_rho_per_mm2(wl, options.sce_table)


def model_spectrum(wavelengths_nm, weights, sce_rho_table_per_mm2,
                   parameters: ModelParameters) -> Spectrum:
    """Spectrum whose chromatic leaves come from ``parameters`` (traceable, vmappable).

    ``wavelengths_nm`` (n,) nm and ``weights`` (n,) (summing to 1) as :func:`make_spectrum`
    makes them; ``sce_rho_table_per_mm2`` (n,) mm⁻² from :func:`sce_rho_table`. LCA (D) is
    A (1/(λ−c) − 1/(λ_ref−c)), the Stiles–Crawford ρ the table times
    ``sce_exponent · sce_rho_scale``, and ``unit_sum`` the normalisation's blend weight —
    computed in the caller's precision (float32 inside a float32 program)."""
    wl = as_real_array(wavelengths_nm)
    rho = as_real_array(sce_rho_table_per_mm2)
    return Spectrum(
        wavelengths_nm=wl,
        weights=as_real_array(weights),
        lca_D=lca_dioptres(wl, parameters),
        sce_rho_per_mm2=rho * (parameters.sce_exponent * parameters.sce_rho_scale),
        unit_sum=parameters.unit_sum,
    )


def monochromatic_spectrum(wavelength_nm: float, options: ModelOptions = ModelOptions()):
    """One-wavelength spectrum (weight 1) at ``wavelength_nm`` (nm, inside
    :func:`computed_range_nm` of ``options``)."""
    return make_spectrum([wavelength_nm], options)


__all__ = [
    "luminous_efficiency",
    "lef_data",
    "lef_range_nm",
    "lca_dioptres",
    "computed_range_nm",
    "check_computed_range",
    "sce_rho_per_mm2",
    "sce_rho_data",
    "Spectrum",
    "make_spectrum",
    "gauss_rule",
    "gauss_spectrum",
    "GAUSS_MAX_NODES",
    "model_spectrum",
    "sce_rho_table",
    "monochromatic_spectrum",
]
