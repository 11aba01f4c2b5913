"""The whole lenslet array rendering a point, not n×n idealised views.

The paper's ideal display, and :meth:`lfjax.display.panel.Panel.layout`, give a rendered point n×n
views whose footprints sit on a fixed grid in the pupil (M·Δu apart, the CDP's spacing) and
whose images are displaced exactly as a real point's. A real integral-imaging display
renders a point at depth D differently: every lenslet k lights the pixel behind it that
lies nearest the line from the point through the lenslet's centre, and that pixel's beam —
the lenslet aperture magnified M times, seen from the pixel's image P_k on the CDP — enters
the eye wherever the line from P_k through the lenslet's centre meets the pupil plane.
:func:`array_views` computes, for a point on the eye's axis, which lenslets do reach the
pupil, where, and how far the pixel grid moves each beam from where the point needs it.

Geometry (mm; lenslets at z_m, CDP at L, the point at z_r = 1000/D; lenslet centres u_k on
a grid of pitch Δu; thin lenses, paraxial):

* the ideal chief ray, from the point through u_k, meets the pupil plane at
  q_k = u_k·z_r/(z_r − z_m) (the paper's Eq. 1: views Δu·z_r/(z_r − z_m) apart) and the
  panel at x_k = u_k − (q_k − u_k)·z_0/z_m;
* the renderer lights the nearest pixel centre x̂_k (pitch p); its beam's chief ray, from
  its image P_k through u_k, meets the pupil plane at q̂_k = u_k − (x̂_k − u_k)·z_m/z_0: the
  quantisation moves the footprint by up to p·z_m/(2z_0) (one pixel of one lenslet is
  z_m·p/z_0 wide at the eye: 24 µm for the near-eye preset, 6.5 mm for the phone panel);
* and it tilts the beam: the chief ray through q̂_k misses the point by the angle
  ε_k = (u_k − q̂_k)/z_m + q̂_k/z_r = (δ_k/z_0)·(1 − z_m/z_r) (rad), δ_k = x̂_k − x_k — on the
  CDP at most half a pixel's angle p/(2·z_0·M) — which the pipeline's display shift (that
  of a ray through the point) does not contain.

A lenslet reaches the pupil geometrically when its footprint (diameter M·a) overlaps it,
and by diffraction when it lies within ``diffraction_widths`` × λ·z_eff/(M·a) of it (the
spread of the magnified aperture's Fresnel pattern over z_eff = z_m·M). The pipeline
propagates each view's aperture from inside the pupil window only, so a lenslet that
reaches the pupil by diffraction alone contributes nothing there; :class:`ArrayViews`
counts them so that a study can say where that matters.

:func:`array_through_focus` runs the pipeline on the lenslets whose footprints overlap the
pupil (each view displaced as a ray through the rendered point, so without the tilt ε_k).
:func:`array_vs_views` computes the whole array independently of the pipeline, at one
wavelength: every lenslet whose lit pixel's diffracted beam reaches the pupil (those that
reach it by diffraction alone included, as the Fresnel field of the magnified aperture by
quadrature, :func:`disc_fresnel_field`), each displaced to its lit pixel's image on the CDP
(tilt included), beside the n×n idealisation computed the same way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

from lfjax.model.layouts import Layout, make_layout
from lfjax.kernel.metrics import ncsf_half_plane
from lfjax.model.options import ModelOptions
from lfjax.display.panel import Panel
from lfjax.kernel.scene import sa_parameters
from lfjax.model.spectral import lca_dioptres, make_spectrum
from lfjax.sweep.guard import host_memory_bytes
from lfjax.vision.focus import through_focus
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing
from lfjax.base.errors import ParameterError
from lfjax.base.types import finite_scalar
from lfjax.base.units import (
    ARCMIN_PER_RADIAN,
    DEGREES_PER_RADIAN,
    check_dioptres,
    dioptres_to_c20_um,
    format_bytes,
)
from lfjax.base.zernike import wavefront_um


@dataclass(frozen=True)
class ArrayViews:
    """Every lenslet beam of a rendered on-axis point that reaches the pupil (host arrays).

    Attributes
    ----------
    depth_D : the rendered depth, D
    lenslet_index : (n, 2) int, the lenslets' grid indices (x, y)
    lenslet_centres_mm : (n, 2) u_k on the lenslet plane, mm
    ideal_centres_mm : (n, 2) q_k, where the ideal beam (through the point) meets the pupil plane, mm
    centres_mm : (n, 2) q̂_k, where the lit pixel's beam meets it, mm
    diameters_mm : (n,) footprint diameter M·a, mm
    tilt_arcmin : (n, 2) ε_k, the lit pixel's beam's angle from a ray through the point, arcmin
    geometric : (n,) bool, the footprint overlaps the pupil (else it reaches by diffraction only)
    pupil_diameter_mm, fresnel_number : the design pupil (mm) and the lenslets' Fresnel number
    """

    depth_D: float
    lenslet_index: np.ndarray
    lenslet_centres_mm: np.ndarray
    ideal_centres_mm: np.ndarray
    centres_mm: np.ndarray
    diameters_mm: np.ndarray
    tilt_arcmin: np.ndarray
    geometric: np.ndarray
    pupil_diameter_mm: float
    fresnel_number: float

    @property
    def n_views(self) -> int:
        return int(self.diameters_mm.shape[0])

    @property
    def n_geometric(self) -> int:
        return int(np.sum(self.geometric))

    def layout(self, name: str | None = None) -> Layout:
        """The views whose footprints overlap the pupil, as a :class:`~lfjax.model.layouts.Layout`
        at the lit pixels' positions (window = the pupil)."""
        keep = self.geometric
        if not np.any(keep):
            raise ValueError(f"no lenslet's footprint overlaps the pupil at {self.depth_D:g} D")
        return make_layout(self.centres_mm[keep], self.diameters_mm[keep], self.pupil_diameter_mm,
                           name=name or f"array at {self.depth_D:g} D",
                           window_diameter_mm=self.pupil_diameter_mm)


def array_views(panel: Panel, depth_D: float, *, wavelength_nm: float = 550.0,
                lattice_offset=None, pixel_offset_mm=(0.0, 0.0),
                diffraction_widths: float = 2.0, emitter_samples: int = 1) -> ArrayViews:
    """The lenslet beams that a point rendered on the eye's axis at ``depth_D`` (D) sends
    towards the pupil of ``panel`` (its design pupil), as its renderer lights them.

    ``lattice_offset`` (in pitches, (x, y)) places the lenslet grid: lenslet centres at
    (k + offset)·Δu; default 0.5 when :meth:`~lfjax.display.panel.Panel.n_views_per_side` is even
    and 0 when odd, the alignment of :meth:`~lfjax.display.panel.Panel.layout`.
    ``pixel_offset_mm`` places the pixel grid: pixel centres at (j + ½)·p + offset on each
    axis. ``diffraction_widths``: how many λ·z_eff/(M·a) beyond its footprint a lenslet's
    beam counts as reaching the pupil. ``emitter_samples`` m splits each lit emitter
    (side p·√pixel_fill) into m×m equal incoherent point sources, each its own beam with
    its own footprint and tilt (m = 1: the emitter's centre), for panels whose emitters
    sweep the footprint across the pupil (:meth:`~lfjax.display.panel.Panel.emitter_sweep_mm`);
    ``lenslet_index`` then repeats per sample. Refuses a depth at or in front of the
    lenslet plane.
    """
    p = float(panel.pixel_pitch_mm)
    du = float(panel.lenslet_pitch_mm)
    zm = float(panel.distance_mm)
    z0 = float(panel.gap_mm)
    m = float(panel.magnification)
    d = float(panel.view_diameter_mm)
    pupil = float(panel.pupil_diameter_mm)
    depth = float(depth_D)
    if not (math.isfinite(depth) and 0.0 <= depth < 1000.0 / zm):
        raise ValueError(f"depth_D must be in [0, {1000.0 / zm:.4g}) D (behind the lenslet plane at "
                         f"{zm:g} mm), got {depth_D}")
    check_dioptres("depth_D", depth, "rendered depth")
    if not (math.isfinite(diffraction_widths) and diffraction_widths >= 0):
        raise ValueError(f"diffraction_widths must be finite and >= 0, got {diffraction_widths}")
    if lattice_offset is None:
        half = 0.5 if panel.n_views_per_side() % 2 == 0 else 0.0
        lattice_offset = (half, half)
    offset = np.asarray(lattice_offset, float).reshape(2)
    pix_off = np.asarray(pixel_offset_mm, float).reshape(2)
    # q = u/(1 − z_m·D/1000): the ideal chief ray through the point (D = 0: parallel rays)
    scale = 1.0 / (1.0 - zm * depth / 1000.0)
    spread = diffraction_widths * wavelength_nm * 1e-6 * float(panel.fresnel_distance_mm) / d
    # the lit pixel lies within half a pixel (plus half an emitter with emitter_samples > 1)
    # of the ideal ray's x_k on each axis, which moves the footprint by up to that times
    # z_m/z_0 from q_k: a lenslet whose ideal footprint is that far outside the pupil can
    # still send its lit beam into it (6.5 mm for the phone's 3x3 against a 3 mm pupil).
    # The search must hold them, or the count depends on the search radius (it counted 21
    # geometric beams for the phone's 3x3 at 1 D with diffraction_widths = 0, 33 with 2,
    # of the 65 there are)
    quantisation = p * (0.5 + (0.5 * math.sqrt(float(panel.pixel_fill)) if emitter_samples > 1
                               else 0.0)) * zm / z0
    reach = 0.5 * pupil + 0.5 * d + spread + quantisation
    k_max = int(math.ceil(reach / (du * scale))) + 2
    if (2 * k_max + 1) ** 2 * max(int(emitter_samples), 1) ** 2 > 4_000_000:
        raise ValueError(f"the beams' reach ({reach:.4g} mm around the pupil) spans {2 * k_max + 1} "
                         f"lenslets a side: lower diffraction_widths (got {diffraction_widths:g}) "
                         f"or emitter_samples (got {emitter_samples})")
    k = np.arange(-k_max, k_max + 1)
    kx, ky = np.meshgrid(k, k)
    index = np.stack([kx.ravel(), ky.ravel()], axis=1)
    u = (index + offset) * du
    q_ideal = u * scale
    x_exact = u - (q_ideal - u) * z0 / zm
    x_pix = (np.round((x_exact - pix_off) / p - 0.5) + 0.5) * p + pix_off
    m_em = int(emitter_samples)
    if m_em != emitter_samples or m_em < 1:
        raise ValueError(f"emitter_samples must be an integer >= 1, got {emitter_samples}")
    if m_em > 1:
        width = p * math.sqrt(float(panel.pixel_fill))
        s1 = ((np.arange(m_em) + 0.5) / m_em - 0.5) * width
        sx, sy = np.meshgrid(s1, s1)
        sub = np.stack([sx.ravel(), sy.ravel()], axis=1)  # (m², 2)
        rep = lambda a: np.repeat(a, m_em * m_em, axis=0)  # noqa: E731
        index, u, q_ideal = rep(index), rep(u), rep(q_ideal)
        x_pix = rep(x_pix) + np.tile(sub, (len(x_pix), 1))
    q = u - (x_pix - u) * zm / z0
    z_r = math.inf if depth == 0 else 1000.0 / depth
    tilt = (u - q) / zm + (0.0 if math.isinf(z_r) else q / z_r)
    dist = np.hypot(q[:, 0], q[:, 1])
    geometric = dist - 0.5 * d < 0.5 * pupil
    keep = dist - 0.5 * d - spread < 0.5 * pupil
    return ArrayViews(depth, index[keep], u[keep], q_ideal[keep], q[keep], np.full(int(keep.sum()), d),
                      tilt[keep] * ARCMIN_PER_RADIAN, geometric[keep], pupil,
                      float(panel.fresnel_number(wavelength_nm)))


def idealisation_gap(panel: Panel, depths_D, *, pixel_offset_mm=(0.0, 0.0),
                     wavelength_nm: float = 550.0) -> list[dict]:
    """How far the whole array's rendering of an on-axis point departs from the n×n
    idealisation (:meth:`~lfjax.display.panel.Panel.layout`), geometrically, per rendered depth.

    Each row (host numbers): ``depth_D``; ``n_idealised`` (n², the layout's views) and
    ``n_array`` (lenslets whose lit pixel's footprint overlaps the pupil);
    ``footprint_shift_mm``, the largest distance between an idealised view's centre and
    where its lenslet's lit beam meets the pupil (the depth's Eq. 1 scaling and the pixel
    grid together; inf when a lit beam misses the pupil); ``tilt_arcmin``, the largest beam tilt ε; ``emitter_sweep_ratio``, the
    emitter sweep over the view width (≪ 1: the pipeline's pixel blur holds); and the
    lenslets' ``fresnel_number`` (≲ 1: beams spread over the pupil). The idealisation holds
    where the shift and the tilt are small beside the view width and the pixel angle,
    ``n_array`` equals ``n_idealised`` and the sweep ratio is small."""
    n = panel.n_views_per_side()
    layout = np.asarray(panel.layout(n).centres_mm, float)
    rows = []
    for depth in np.atleast_1d(np.asarray(depths_D, float)):
        views = array_views(panel, float(depth), pixel_offset_mm=pixel_offset_mm,
                            wavelength_nm=wavelength_nm, diffraction_widths=0.0)
        shift = 0.0
        m = float(panel.magnification)
        tol = 1e-9 * float(panel.lenslet_pitch_mm)
        for centre in layout:  # the idealised view of lenslet u = centre/M
            mine = np.all(np.abs(views.lenslet_centres_mm - centre / m) <= tol, axis=1)
            if np.any(mine):
                shift = max(shift, float(np.max(np.hypot(*(views.centres_mm[mine] - centre).T))))
            else:  # that lenslet's lit beam misses the pupil altogether
                shift = math.inf
        rows.append(dict(
            depth_D=float(depth), n_idealised=n * n, n_array=views.n_geometric,
            footprint_shift_mm=shift,
            tilt_arcmin=float(np.max(np.abs(views.tilt_arcmin))) if views.n_views else 0.0,
            emitter_sweep_ratio=float(panel.emitter_sweep_mm()) / float(panel.view_diameter_mm),
            fresnel_number=views.fresnel_number))
    return rows


def array_through_focus(eyes, panel: Panel, depths_D, accommodation_D, *, diffraction=None,
                        pixel_offset_mm=(0.0, 0.0), **kwargs):
    """Through-focus curves of points rendered by the whole array: one
    :func:`lfjax.vision.focus.through_focus` per rendered depth, each with the layout of
    :func:`array_views` (the lenslets whose footprints overlap the pupil, at the lit
    pixels' positions) and the panel's optics (``diffraction`` overrides its mode).
    ``accommodation_D`` (n_acc,) D is every depth's absolute grid; ``kwargs`` go to
    ``through_focus`` (``spectrum``, ``sampling``, ``options``, ``peaks``, …). The
    beams' tilts ε_k are not in these images (module docstring). Returns a list of
    (ArrayViews, ThroughFocus), one per depth."""

    optics = panel.optics(diffraction)
    out = []
    for depth in np.atleast_1d(np.asarray(depths_D, float)):
        views = array_views(panel, float(depth), pixel_offset_mm=pixel_offset_mm)
        viewing = Viewing(pupil_diameter_mm=panel.pupil_diameter_mm, cdp_D=float(panel.cdp_D),
                          display=optics)
        tf = through_focus(eyes, views.layout(), States.grid(accommodation_D, [depth]), viewing,
                           **kwargs)
        out.append((views, tf))
    return out





# ----------------------------------------------------------------------------- diffraction


def _disc_fresnel_table(radius_mm: float, wavelength_nm: float, distance_mm: float, r_max_mm: float):
    """(radial grid (mm), the Fresnel integral without its outer chirp on it): see
    :func:`disc_fresnel_field`."""
    from scipy.special import j0

    lam_z = wavelength_nm * 1e-6 * distance_mm
    rho0 = float(radius_mm)
    step = lam_z / rho0 / 50.0
    grid = np.arange(0.0, float(r_max_mm) + 2 * step, step)
    # cycles of the integrand over [0, ρ₀]: the chirp's N/2 and J₀'s r·ρ₀/(λz)
    cycles = rho0 * rho0 / (2 * lam_z) + float(r_max_mm) * rho0 / lam_z
    # composite Gauss–Legendre: 16 nodes on each of two panels per cycle (a single rule of
    # thousands of nodes costs an eigenproblem of that size)
    n_panels = int(min(1_000, 4 + 2 * math.ceil(cycles)))
    x, w = np.polynomial.legendre.leggauss(16)
    edges = np.linspace(0.0, rho0, n_panels + 1)
    half = 0.5 * np.diff(edges)[:, None]
    rho = (0.5 * (edges[:-1] + edges[1:])[:, None] + half * x[None, :]).ravel()
    weights = (half * w[None, :]).ravel()
    n_nodes = rho.size
    inner = np.exp(1j * np.pi * rho * rho / lam_z) * rho * weights
    values = np.empty(grid.size, complex)
    block = max(1, 4_000_000 // n_nodes)
    for start in range(0, grid.size, block):
        g = grid[start:start + block]
        values[start:start + block] = j0(2 * np.pi * np.outer(g, rho) / lam_z) @ inner
    return grid, values


def _disc_fresnel_at(table, wavelength_nm: float, distance_mm: float, r_mm):
    grid, values = table
    lam_z = wavelength_nm * 1e-6 * distance_mm
    r = np.asarray(r_mm, float)
    smooth = np.interp(r, grid, values.real) + 1j * np.interp(r, grid, values.imag)
    return (2 * np.pi / (1j * lam_z)) * np.exp(1j * np.pi * r * r / lam_z) * smooth


def disc_fresnel_field(radius_mm: float, wavelength_nm: float, distance_mm: float, r_mm):
    """Fresnel field of a uniformly lit disc of ``radius_mm`` (amplitude 1) after
    ``distance_mm``, at radii ``r_mm`` (any shape, mm) from the disc's axis; complex, host
    float64.

    U(r) = (2π/(iλz)) exp(iπr²/(λz)) ∫₀^ρ₀ exp(iπρ²/(λz)) J₀(2πrρ/(λz)) ρ dρ — the Fresnel
    integral in polar form with the constant phase exp(ikz) dropped, so U → 1 inside the
    disc as z → 0 (the convention of :func:`lfjax.base.apertures.fresnel_propagate`, which this
    computes independently: a Gauss–Legendre quadrature in ρ, not a discrete convolution).
    The integral (without the outer chirp) varies with r on the scale λz/ρ₀; it is
    evaluated on a radial grid 50 points to that scale and interpolated linearly."""
    r = np.asarray(r_mm, float)
    table = _disc_fresnel_table(radius_mm, wavelength_nm, distance_mm, float(np.max(r)) if r.size else 0.0)
    return _disc_fresnel_at(table, wavelength_nm, distance_mm, r)


def _fast_len(n: int) -> int:
    from scipy.fft import next_fast_len

    return int(next_fast_len(int(n)))


@dataclass(frozen=True)
class ViewCurves:
    """Through-focus VSOTF of a point rendered by a set of diffracted views (host arrays).

    Attributes
    ----------
    accommodation_D : (n_states,) D
    vsotf : (n_states,) Σ NCSF·Re OTF over the reference's (the pipeline's: the idealised
        views of the same panel as geometric footprints, no aberrations, accommodated on
        the CDP and the point rendered on it)
    n_views : views summed
    energy : (n_views,) the power each view's beam brings through the pupil, relative to a
        beam that fills its geometric footprint inside the pupil (1 for a central view of a
        large Fresnel number)
    dropped_energy_fraction : the share of the considered beams' power left out as below
        ``min_view_energy`` (reported, never hidden)
    diffraction_only_fraction : the share of the summed beams' power brought by lenslets
        whose geometric footprint misses the pupil (0 for the idealised views)
    """

    accommodation_D: np.ndarray
    vsotf: np.ndarray
    n_views: int
    energy: np.ndarray
    dropped_energy_fraction: float
    diffraction_only_fraction: float


def _view_vsotf_numerators(zernike_um, measured_pupil_mm: float, panel: Panel, accommodation_D,
                           centres_mm, shifts_rad, wavelength_nm: float, freq_step_cpd: float,
                           options, min_view_energy: float, chunk: int, diffracted: bool = True):
    """Σ NCSF·Re OTF (OTF(0) = 1) per accommodation state of incoherent diffracted views:
    view k's pupil field is the Fresnel pattern of the magnified lenslet aperture centred on
    ``centres_mm[k]`` times the eye's pupil (Stiles–Crawford amplitude, aberrations,
    defocus from the CDP, accommodation SA), its PSF displaced by ``shifts_rad[k]`` (the
    pipeline's sign: the phase ramp exp(−2πi f·Δθ) on its OTF). Returns (numerators
    (n_states,), every view's energy, the views kept, the dropped share of the energy))."""
    from scipy import fft as sfft


    lam_mm = wavelength_nm * 1e-6
    pupil = float(panel.pupil_diameter_mm)
    radius = 0.5 * pupil
    df_rad = freq_step_cpd * DEGREES_PER_RADIAN
    dx = lam_mm * df_rad
    n_p = int(math.ceil(pupil / dx)) + 2
    n_p += n_p % 2
    n_fft = _fast_len(2 * n_p)
    offsets = (np.arange(n_p) - n_p // 2) * dx
    xx, yy = np.meshgrid(offsets, offsets)  # [y, x]
    r2 = xx * xx + yy * yy
    inside = r2 <= radius * radius
    rho = float(np.asarray(make_spectrum([wavelength_nm], options).sce_rho_per_mm2)[0])
    amplitude = np.where(inside, 10.0 ** (-rho * r2), 0.0)  # ρ carries the SCE's form
    z = np.array(zernike_um, float).reshape(-1)
    if options.zero_piston_tilt:
        z[:3] = 0.0
    r_meas = 0.5 * float(measured_pupil_mm)
    eye = np.asarray(wavefront_um(jnp.asarray(z), jnp.asarray(xx / r_meas), jnp.asarray(yy / r_meas)), float)
    rn2 = r2 / (radius * radius)
    z20 = math.sqrt(3.0) * (2 * rn2 - 1)
    sa_per_D, sa_radius = (float(v) for v in np.asarray(sa_parameters(options, pupil)))
    rs2 = r2 / (sa_radius * sa_radius)
    z40 = math.sqrt(5.0) * (6 * rs2 * rs2 - 6 * rs2 + 1)
    lca = float(np.asarray(lca_dioptres(np.asarray([wavelength_nm]), options))[0])
    cdp = float(panel.cdp_D)
    # the beams: the magnified aperture's Fresnel pattern over z_eff, centred on each view
    d = float(panel.view_diameter_mm)
    z_eff = float(panel.fresnel_distance_mm)
    centres = np.asarray(centres_mm, float).reshape(-1, 2)
    shifts = np.asarray(shifts_rad, float).reshape(-1, 2)
    beams = []
    energy = np.empty(len(centres))
    if not len(centres):
        raise ValueError("no lenslet's beam reaches the pupil at this depth")
    r_max = float(np.max(np.hypot(centres[:, 0], centres[:, 1]))) + radius + dx if len(centres) else 0.0
    table = _disc_fresnel_table(0.5 * d, wavelength_nm, z_eff, r_max)
    for k, c in enumerate(centres):
        distance = np.hypot(xx - c[0], yy - c[1])
        b = (_disc_fresnel_at(table, wavelength_nm, z_eff, distance) if diffracted
             else (distance <= 0.5 * d).astype(float))
        b = np.where(inside, b, 0.0)
        beams.append(b)
        energy[k] = float(np.sum(np.abs(b) ** 2)) * dx * dx
    full = min(math.pi * d * d / 4.0, math.pi * radius * radius)
    energy = energy / full
    keep = energy >= min_view_energy * float(np.max(energy))
    dropped = float(np.sum(energy[~keep]) / np.sum(energy))
    beams = np.stack([b for b, k in zip(beams, keep) if k]).astype(np.complex64)
    shifts = shifts[keep]
    fy = np.fft.fftfreq(n_fft, 1.0 / n_fft) * df_rad
    fx = np.fft.rfftfreq(n_fft, 1.0 / n_fft) * df_rad
    ramp = (np.exp(-2j * np.pi * shifts[:, 1, None, None] * fy[None, :, None])
            * np.exp(-2j * np.pi * shifts[:, 0, None, None] * fx[None, None, :])).astype(np.complex64)
    weighted_ncsf = np.asarray(ncsf_half_plane(n_fft, freq_step_cpd, options.ncsf), float)
    out = []
    for a in np.asarray(accommodation_D, float).reshape(-1):
        c20 = float(dioptres_to_c20_um(a - cdp + lca, pupil))
        w_um = eye + c20 * z20 + sa_per_D * a * z40
        pupil_field = (amplitude * np.exp(-2j * np.pi * w_um / (wavelength_nm * 1e-3))).astype(np.complex64)
        otf = np.zeros((n_fft, n_fft // 2 + 1), np.complex128)
        for start in range(0, len(beams), chunk):
            field = beams[start:start + chunk] * pupil_field
            spec = sfft.fft2(field, s=(n_fft, n_fft), workers=-1)
            psf = (spec.real ** 2 + spec.imag ** 2).astype(np.float32)
            otf += np.sum(sfft.rfft2(psf, workers=-1) * ramp[start:start + chunk], axis=0)
        otf /= otf[0, 0].real
        out.append(float(np.sum(otf.real * weighted_ncsf)))
    return np.asarray(out), energy, keep, dropped


def _idealised_views(panel: Panel, depth_D: float):
    """The n×n layout's centres (mm) and the pipeline's displacement (D − D_CDP)·p (rad)."""
    centres = np.asarray(panel.layout(panel.n_views_per_side()).centres_mm, float)
    return centres, (float(depth_D) - float(panel.cdp_D)) * centres * 1e-3


def _array_views_shifts(panel: Panel, views: ArrayViews):
    """Displacement of each lit pixel's image (rad, the pipeline's sign): the image P_k of
    the pixel on the CDP lies at X_k = u_k + (u_k − q̂_k)(L − z_m)/z_m (the line from P_k
    through the lenslet centre u_k meets the pupil plane at q̂_k), seen at −X_k/L; for an
    ideal renderer this is the pipeline's (D − D_CDP)·q."""
    zm = float(panel.distance_mm)
    cdp = float(panel.cdp_D)
    u, q = views.lenslet_centres_mm, views.centres_mm
    if cdp == 0:  # CDP at infinity: the image's angle is that of the beam, (u − q)/z_m
        return (u - q) / zm
    length = 1000.0 / cdp
    x_cdp = u + (u - q) * (length - zm) / zm
    return -x_cdp / length


MIN_PUPIL_SAMPLES = 16
"""Fewest samples of λ·Δf (the pupil-plane step a frequency step Δf sets) across the design
pupil :func:`array_vs_views` accepts: coarser, the field of view (1/Δf degrees) no longer
holds an aberrated eye's PSF and the pupil's edge is a handful of samples."""


def max_freq_step_cpd(panel: Panel, wavelength_nm: float) -> float:
    """The coarsest frequency step :func:`array_vs_views` accepts, cpd: the design pupil
    spans :data:`MIN_PUPIL_SAMPLES` samples of λ·Δf."""
    return float(panel.pupil_diameter_mm) / (MIN_PUPIL_SAMPLES * wavelength_nm * 1e-6
                                             * DEGREES_PER_RADIAN)


def _grid_sizes(panel: Panel, wavelength_nm: float, freq_step_cpd: float) -> tuple[int, int]:
    """(pupil samples a side, FFT length) of :func:`_view_vsotf_numerators`."""
    dx = wavelength_nm * 1e-6 * freq_step_cpd * DEGREES_PER_RADIAN
    n_p = int(math.ceil(float(panel.pupil_diameter_mm) / dx)) + 2
    n_p += n_p % 2
    return n_p, _fast_len(2 * n_p)


def array_vs_views_bytes(panel: Panel, n_views: int, wavelength_nm: float, freq_step_cpd: float,
                         chunk: int) -> float:
    """Peak host memory of one curve of :func:`array_vs_views` on ``n_views`` beams, bytes,
    estimated from its arrays: the largest of its three phases — building the beams' pupil
    fields (complex128, then stacked as complex64), building their phase ramps on the
    half-plane FFT grid (complex128, kept as complex64), and the FFTs of ``chunk`` views at a
    time beside both — plus a dozen pupil-sized grids and the Fresnel table's blocks.
    Against tracemalloc's peak on the phone panel's 76 beams (one state, chunk 32): 1.10x
    it at 0.5 cpd (238 MB measured), 1.26x at 0.3 cpd (493 MB)."""
    n_p, n_fft = _grid_sizes(panel, wavelength_nm, freq_step_cpd)
    half = n_fft * (n_fft // 2 + 1)
    views = max(int(n_views), 1)
    pupils = views * n_p * n_p
    phases = (pupils * 24,                       # beams as built, and stacked
              pupils * 8 + views * half * 24,    # the ramps as built, and kept
              pupils * 8 + views * half * 8      # one chunk's FFTs beside both
              + min(int(chunk), views) * (n_fft * n_fft * 20 + half * 16))
    return float(max(phases) + 16 * n_p * n_p * 8 + half * 24 + 48e6)


def check_array_vs_views_memory(panel: Panel, n_views: int, wavelength_nm: float,
                                freq_step_cpd: float, chunk: int,
                                available_bytes: float | None = None) -> float:
    """Refuse (naming ``freq_step_cpd``) an :func:`array_vs_views` whose estimated memory
    (:func:`array_vs_views_bytes`) exceeds ``available_bytes`` (default: this machine's
    available memory), saying the finest step that would fit. Returns the estimate."""
    have = host_memory_bytes() if available_bytes is None else float(available_bytes)
    need = array_vs_views_bytes(panel, n_views, wavelength_nm, freq_step_cpd, chunk)
    if need <= have:
        return need
    top = max_freq_step_cpd(panel, wavelength_nm)
    step = float(freq_step_cpd)
    while step < top and array_vs_views_bytes(panel, n_views, wavelength_nm, step, 1) > have:
        step *= 2 ** 0.125
    fits = (f"freq_step_cpd >= {step:.3g} cpd with chunk = 1 would fit "
            f"(~{format_bytes(array_vs_views_bytes(panel, n_views, wavelength_nm, step, 1))})"
            if step <= top else f"no step up to {top:.3g} cpd fits: fewer beams (a smaller "
                                "beams.diffraction_widths) or more memory")
    n_p, n_fft = _grid_sizes(panel, wavelength_nm, freq_step_cpd)
    raise ParameterError(
        "freq_step_cpd", "{freq_step_cpd} = {step:g} cpd would need ~{need} of memory ({views} "
        "beams, pupil grids {n_p}x{n_p}, FFTs {n_fft}x{n_fft}, {chunk} at a time), {have} "
        "available: {fits}", step=float(freq_step_cpd), need=format_bytes(need), views=int(n_views),
        n_p=n_p, n_fft=n_fft, chunk=int(chunk), have=format_bytes(have), fits=fits)


@dataclass(frozen=True)
class ArrayBeams:
    """Which of the whole array's beams :func:`array_vs_views` sums, and where the lit
    pixels sit (checked when built, a :class:`~lfjax.base.errors.ParameterError` naming the
    field).

    Attributes
    ----------
    diffraction_widths : how many λ·z_eff/(M·a) beyond its footprint a lenslet's beam counts
        as reaching the pupil (:func:`array_views`), ≥ 0
    min_view_energy : beams bringing less than this share of the strongest beam's power
        through the pupil are left out (the share they carried is reported), in [0, 1)
    pixel_offset_mm : (x, y) offset of the pixel grid, mm: pixel centres at (j + ½)·p +
        offset on each axis
    """

    diffraction_widths: float = 3.0
    min_view_energy: float = 1e-3
    pixel_offset_mm: tuple = (0.0, 0.0)

    def __post_init__(self):
        finite_scalar("diffraction_widths", self.diffraction_widths, 0.0)
        finite_scalar("min_view_energy", self.min_view_energy, 0.0)
        if not self.min_view_energy < 1.0:
            raise ParameterError("min_view_energy", "{min_view_energy} must be in [0, 1), got "
                                 "{got}", got=self.min_view_energy)
        offset = np.asarray(self.pixel_offset_mm, float)
        if offset.shape != (2,) or not np.all(np.isfinite(offset)):
            raise ParameterError("pixel_offset_mm", "{pixel_offset_mm} must be two finite "
                                 "numbers (x, y) in mm, got {got!r}", got=self.pixel_offset_mm)
        # a tuple of floats keeps the object hashable whatever sequence was given
        object.__setattr__(self, "pixel_offset_mm", tuple(float(x) for x in offset))


def _check_array_vs_views(zernike_um, measured_pupil_mm, panel, depth_D, accommodation_D,
                          wavelength_nm, freq_step_cpd, options, beams, chunk) -> np.ndarray:
    """:func:`array_vs_views`' checks of its arguments, before any work; returns the states
    (n_states,) D."""
    if not isinstance(panel, Panel):
        raise ParameterError("panel", "{panel} must be lfjax.display.panel.Panel, got {got}",
                             got=type(panel).__name__)
    if panel.aperture != "circle":
        raise ParameterError("panel", "array_vs_views models circular lenslets only, got "
                             "{panel}.aperture = {got!r}", got=panel.aperture)
    z = np.asarray(zernike_um, float)
    if z.ndim != 1 or z.size < 1:
        raise ParameterError("zernike_um", "{zernike_um} must be one eye's coefficients, shape "
                             "(n_modes,), got shape {shape}", shape=z.shape)
    if not np.all(np.isfinite(z)):
        raise ParameterError("zernike_um", "{zernike_um} must be finite, got NaN or inf at "
                             "modes {modes}", modes=np.nonzero(~np.isfinite(z))[0].tolist())
    measured = finite_scalar("measured_pupil_mm", measured_pupil_mm, 0.0, lo_open=True)
    pupil = float(panel.pupil_diameter_mm)
    if pupil > measured + 1e-9:
        raise ParameterError("measured_pupil_mm", "{measured_pupil_mm} = {measured:g} mm is "
                             "smaller than the panel's design pupil {pupil:g} mm: the "
                             "coefficients are defined inside the measured pupil only",
                             measured=measured, pupil=pupil)
    wl = finite_scalar("wavelength_nm", wavelength_nm, 0.0, lo_open=True)
    make_spectrum([wl], options)  # the model's wavelengths (its data's range)
    top = max_freq_step_cpd(panel, wl)
    step = finite_scalar("freq_step_cpd", freq_step_cpd, 0.0, lo_open=True)
    if step > top:
        raise ParameterError("freq_step_cpd", "{freq_step_cpd} must be in (0, {top:.3g}] cpd "
                             "(the {pupil:g} mm pupil spans at least {n} samples of "
                             "wavelength x step), got {step:g}", top=top, pupil=pupil,
                             n=MIN_PUPIL_SAMPLES, step=step)
    check_dioptres("depth_D", depth_D, "rendered depth")
    acc = np.asarray(accommodation_D, float).reshape(-1)
    if acc.size == 0:
        raise ParameterError("accommodation_D", "{accommodation_D} must hold at least one state")
    check_dioptres("accommodation_D", acc, "accommodation state")
    if not isinstance(beams, ArrayBeams):
        raise ParameterError("beams", "{beams} must be lfjax.studies.array_views.ArrayBeams, "
                             "got {got}", got=type(beams).__name__)
    if isinstance(chunk, bool) or int(chunk) != chunk or chunk < 1:
        raise ParameterError("chunk", "{chunk} must be an integer >= 1 (views transformed "
                             "together), got {got!r}", got=chunk)
    return acc


def array_vs_views(zernike_um, measured_pupil_mm: float, panel: Panel, depth_D: float,
                   accommodation_D, *, wavelength_nm: float = 550.0, freq_step_cpd: float = 0.5,
                   options=None, beams: ArrayBeams = ArrayBeams(),  # noqa: B008 (frozen)
                   chunk: int = 32, available_bytes: float | None = None) -> dict[str, ViewCurves]:
    """Through-focus VSOTF of one eye for a point on the axis at ``depth_D`` (D), rendered
    (a) by the panel's n×n idealised views (``"idealised"``: the layout of
    :meth:`~lfjax.display.panel.Panel.layout`, each displaced as a ray through the point — what the
    pipeline computes) and (b) by the whole array (``"array"``: every lenslet whose lit
    pixel's diffracted beam reaches the pupil, within ``beams.diffraction_widths`` ×
    λ·z_eff/(M·a) of it, at the lit pixel's footprint and displaced to the lit pixel's image),
    one wavelength (``wavelength_nm``), on a frequency step ``freq_step_cpd`` (cpd).

    An independent, host float64/complex64 computation (diffracted beams by
    :func:`disc_fresnel_field`, one FFT pair per view and state), for studies; its
    idealised curves agree with the pipeline's (``tests/studies/test_array_views.py``). Beams
    bringing less than ``beams.min_view_energy`` of the strongest beam's power through the
    pupil are left out, and the share they carried is reported (:class:`ArrayBeams`: which
    beams, and the pixel grid's offset). Circular lenslets only.

    ``zernike_um`` (n_modes,) µm on ``measured_pupil_mm``; ``accommodation_D`` (n_states,) D.
    ``chunk``: views Fourier transformed together (an integer >= 1).

    Every argument is checked before any work (a :class:`~lfjax.base.errors.ParameterError`
    naming it): finite coefficients, a measured pupil holding the panel's design pupil,
    depth and states in the model's range (:func:`~lfjax.base.units.check_dioptres`),
    ``freq_step_cpd`` in (0, :func:`max_freq_step_cpd`], and the memory the computation
    needs (:func:`array_vs_views_bytes`) within ``available_bytes`` (default: what this
    machine has available): a step too fine to fit is refused with the step and chunk that
    would.
    """
    options = ModelOptions() if options is None else options
    acc = _check_array_vs_views(zernike_um, measured_pupil_mm, panel, depth_D, accommodation_D,
                                wavelength_nm, freq_step_cpd, options, beams, chunk)
    # the whole array's beams (geometry only, cheap): their count sizes the memory
    views = array_views(panel, float(depth_D), wavelength_nm=wavelength_nm,
                        diffraction_widths=beams.diffraction_widths,
                        pixel_offset_mm=beams.pixel_offset_mm)
    check_array_vs_views_memory(panel, views.n_views, wavelength_nm, freq_step_cpd, chunk,
                                available_bytes)
    common = dict(wavelength_nm=wavelength_nm, freq_step_cpd=freq_step_cpd, options=options,
                  chunk=chunk)
    ref_centres, ref_shifts = _idealised_views(panel, float(panel.cdp_D))
    # the pipeline's reference: the idealised views of an ideal display (geometric footprints)
    reference, _, _, _ = _view_vsotf_numerators(
        np.zeros(3), measured_pupil_mm, panel, [float(panel.cdp_D)], ref_centres, ref_shifts,
        min_view_energy=0.0, diffracted=False, **common)
    out = {}
    centres, shifts = _idealised_views(panel, depth_D)
    values, energy, keep, dropped = _view_vsotf_numerators(
        zernike_um, measured_pupil_mm, panel, acc, centres, shifts, min_view_energy=0.0, **common)
    out["idealised"] = ViewCurves(acc, values / reference[0], int(keep.sum()), energy[keep], dropped, 0.0)
    values, energy, keep, dropped = _view_vsotf_numerators(
        zernike_um, measured_pupil_mm, panel, acc, views.centres_mm, _array_views_shifts(panel, views),
        min_view_energy=beams.min_view_energy, **common)
    by_diffraction = float(np.sum(energy[keep & ~views.geometric]) / np.sum(energy[keep]))
    out["array"] = ViewCurves(acc, values / reference[0], int(keep.sum()), energy[keep], dropped,
                              by_diffraction)
    return out


__all__ = ["ArrayBeams", "ArrayViews", "array_views", "idealisation_gap", "array_through_focus", "ViewCurves",
           "disc_fresnel_field", "array_vs_views", "array_vs_views_bytes",
           "check_array_vs_views_memory", "max_freq_step_cpd", "MIN_PUPIL_SAMPLES"]
