"""Model options: every modelling choice the paper leaves open, as one named field.

The defaults reproduce Miyanishi et al. as docs/design.md#modelling-choices reads it.

Two faces of one model:

* :class:`ModelOptions` — the public face: a frozen, hashable dataclass of named choices
  (strings) and physical constants (floats), checked on the host. Only the choices that
  select code or set array shapes reach the compiled pipeline as static configuration
  (``ncsf``, ``vsotf_reference``, ``zero_piston_tilt``, through
  :class:`lfjax.kernel.pipeline.PipelineConfig`); ``sce_table`` selects host data (the ρ(λ)
  column).
* :class:`ModelParameters` — everything else as numbers, each a traced leaf of an equinox
  Module: the physical constants and the numeric form of each remaining choice
  (:meth:`ModelOptions.parameters` maps one to the other). ``jax.grad`` and ``jax.vmap``
  apply to it; changing any of its values does not recompile. The spectrum
  (:func:`lfjax.model.spectral.model_spectrum`) and the accommodation states
  (:meth:`lfjax.kernel.scene.Accommodation.shared`) are computed from it.
"""

from __future__ import annotations

import dataclasses
import types
from dataclasses import dataclass

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from lfjax.base.types import as_real_array, is_concrete

SCE_FORMS = ("amplitude", "intensity", "off")
ACCOMMODATION_SA_FORMS = ("scaled", "wavefront_5mm", "unscaled", "off")
VSOTF_REFERENCES = ("paper", "open_pupil")
NCSF_MODELS = ("watson_ahumada_2005", "campbell_green_2004")
WAVELENGTH_NORMALISATIONS = ("transmitted_energy", "unit_sum")
SCE_TABLES = (
    "isetbio_berendschot_data",
    "isetbio_berendschot_model_as_coded",
    "isetbio_berendschot_model_outlier_removed",
    "figure2_digitized_raw_unshifted",
)

SCE_EXPONENTS = {"amplitude": 1.0, "intensity": 0.5, "off": 0.0}
"""``ModelOptions.sce`` as a number e: the pupil amplitude is A = 10^(−e·s·ρ(λ)·r²) (s the
ρ scale factor, r in mm), so the intensity weight is 10^(−2e·s·ρ r²)."""

ACCOMMODATION_SA_NUMBERS = {
    "scaled": (1.0, 4.0, 0.0),
    "wavefront_5mm": (1.0, 0.0, 1.0),
    "unscaled": (1.0, 0.0, 0.0),
    "off": (0.0, 0.0, 0.0),
}
"""``ModelOptions.accommodation_sa`` as numbers (gain g, pupil exponent p, reference-radius
weight w): the calculation adds c(4,0) = slope · a · g · (d/d_ref)^p on the Zernike pupil of
radius ½(d + w·(d_ref − d)), d the calculation pupil and d_ref the reference pupil (mm)."""

WAVELENGTH_NORMALISATION_NUMBERS = {"transmitted_energy": 0.0, "unit_sum": 1.0}
"""``ModelOptions.wavelength_normalisation`` as a blend weight u: each wavelength's weight is
divided by (energy all views transmit at λ)^u."""


@dataclass(frozen=True)
class ModelOptions:
    """Modelling choices and physical constants of the eye + display model (host side).

    The strings name choices; :meth:`parameters` turns the constants and the numeric form of
    every choice that neither selects code nor sets a shape into a :class:`ModelParameters`
    of traced leaves (``SCE_EXPONENTS``, ``ACCOMMODATION_SA_NUMBERS``,
    ``WAVELENGTH_NORMALISATION_NUMBERS``).

    Attributes
    ----------
    sce : str
        Stiles–Crawford apodisation of the pupil *amplitude*. ``"amplitude"`` (default, as
        the paper and ISETBio write it): A = 10^(−ρ r²), so the intensity weight is
        10^(−2ρ r²). ``"intensity"``: A = 10^(−ρ r²/2), consistent with ρ being defined on
        luminous efficiency (intensity). ``"off"``: A = 1.
    sce_table : str
        Column of ``lfjax/data/stiles_crawford_rho.csv`` giving ρ(λ) in mm⁻².
    sce_rho_scale : float
        Factor on the table's ρ(λ), unitless, ≥ 0 (1: the table as it is).
    accommodation_sa : str
        How the accommodation-dependent spherical aberration (``sa_slope_um_per_D`` × a on a
        ``sa_reference_pupil_mm`` pupil, a = absolute accommodation in D) reaches the
        calculation pupil. ``"scaled"`` (default): c(4,0) × (d/5)⁴ added to the calculation
        pupil's c(4,0) (the exact rescaling, its induced defocus absorbed in the
        accommodation variable). ``"wavefront_5mm"``: the 5 mm Zernike term evaluated
        inside the calculation pupil (keeps the induced defocus). ``"unscaled"``: the 5 mm
        coefficient added unchanged to the calculation pupil's c(4,0). ``"off"``.
    sa_slope_um_per_D : float
        Change of c(4,0) per dioptre of accommodation, µm/D (Cheng et al. 2004: −0.0435).
    sa_reference_pupil_mm : float
        Pupil diameter (mm) on which ``sa_slope_um_per_D`` was measured (5 mm).
    lca_A : float
        Constant A of the LCA model D(λ) = A (1/(λ−c) − 1/(λ_ref−c)), in D·nm. The paper's
        633.26 by default; Thibos et al. (1992) printed 633.46.
    lca_c_nm : float
        Constant c of the LCA model, nm (214.10).
    lca_reference_nm : float
        Wavelength in focus for zero accommodation error, nm (550).
    vsotf_reference : str
        Reference OTF of VSOTF and Strehl. ``"paper"``: the same layout with zero
        monochromatic aberrations, accommodated on the CDP and the point rendered on the
        CDP, accommodation SA and LCA kept. ``"open_pupil"``: the same but through the open
        natural pupil, so LF layouts are scored against natural viewing.
    ncsf : str
        Neural contrast-sensitivity model weighting VSOTF (see :mod:`lfjax.kernel.metrics`).
    zero_piston_tilt : bool
        Drop j = 0, 1, 2 from eye coefficients (tilt only shifts the PSF).
    wavelength_normalisation : str
        How each wavelength's PSF enters the polychromatic sum Σ_λ w(λ) PSF_λ.
        ``"transmitted_energy"`` (default): PSF_λ carries the energy its Stiles–Crawford
        apodised pupil transmits at λ, the paper's ePSF_poly = ∫ ePSF(λ) V(λ) dλ read
        literally — a wavelength whose pupil is more strongly apodised (larger ρ(λ)) counts
        for less, as it does for the photoreceptors. ``"unit_sum"``: each wavelength's PSF
        (summed over the views) is scaled to unit volume before weighting, as ISETBio does
        (``oiCompute`` normalises each wavelength's PSF; the paper's code was customised
        ISETBio); the views keep their ratios within a wavelength. The two differ by a few
        1e-3 in VSOTF on the natural view (benchmarks/RESULTS.md). The default stays with
        the paper's equation, which an independent brute-force computation reproduces.
    """

    sce: str = "amplitude"
    sce_table: str = "isetbio_berendschot_data"
    accommodation_sa: str = "scaled"
    sa_slope_um_per_D: float = -0.0435
    sa_reference_pupil_mm: float = 5.0
    lca_A: float = 633.26
    lca_c_nm: float = 214.10
    lca_reference_nm: float = 550.0
    vsotf_reference: str = "paper"
    ncsf: str = "watson_ahumada_2005"
    zero_piston_tilt: bool = True
    wavelength_normalisation: str = "transmitted_energy"
    sce_rho_scale: float = 1.0

    def __post_init__(self):
        for name, allowed in (
            ("sce", SCE_FORMS),
            ("sce_table", SCE_TABLES),
            ("accommodation_sa", ACCOMMODATION_SA_FORMS),
            ("vsotf_reference", VSOTF_REFERENCES),
            ("ncsf", NCSF_MODELS),
            ("wavelength_normalisation", WAVELENGTH_NORMALISATIONS),
        ):
            value = getattr(self, name)
            if value not in allowed:
                raise ValueError(f"ModelOptions.{name}={value!r}; allowed: {', '.join(allowed)}")
        if not (self.lca_c_nm < 380.0):
            raise ValueError(f"ModelOptions.lca_c_nm must be < 380 nm, got {self.lca_c_nm}")
        if self.sa_reference_pupil_mm <= 0:
            raise ValueError(
                f"ModelOptions.sa_reference_pupil_mm must be > 0, got {self.sa_reference_pupil_mm}"
            )
        if not (self.sce_rho_scale >= 0):
            raise ValueError(f"ModelOptions.sce_rho_scale must be >= 0, got {self.sce_rho_scale}")

    def numbers(self) -> dict[str, float]:
        """The numeric model as Python floats, keyed like :class:`ModelParameters`' leaves
        (the host computes with them in float64, as it always has)."""
        gain, exponent, radius_weight = ACCOMMODATION_SA_NUMBERS[self.accommodation_sa]
        return dict(
            lca_A=float(self.lca_A), lca_c_nm=float(self.lca_c_nm),
            lca_reference_nm=float(self.lca_reference_nm),
            sa_slope_um_per_D=float(self.sa_slope_um_per_D),
            sa_reference_pupil_mm=float(self.sa_reference_pupil_mm), sa_gain=gain,
            sa_pupil_exponent=exponent, sa_reference_radius_weight=radius_weight,
            sce_exponent=SCE_EXPONENTS[self.sce], sce_rho_scale=float(self.sce_rho_scale),
            unit_sum=WAVELENGTH_NORMALISATION_NUMBERS[self.wavelength_normalisation],
        )

    def parameters(self) -> ModelParameters:
        """The numeric model: constants and the numeric form of each choice, as array
        leaves (:class:`ModelParameters`)."""
        return ModelParameters(**self.numbers())

    def static_choices(self) -> dict:
        """The choices that select code or set array shapes (equal options compile once)."""
        return {name: getattr(self, name) for name in STATIC_CHOICES}

    def replace(self, **changes) -> ModelOptions:
        """A copy with some fields changed."""
        return dataclasses.replace(self, **changes)

    def as_dict(self) -> dict:
        """Plain dict (for file attributes)."""
        return dataclasses.asdict(self)


STATIC_CHOICES = ("ncsf", "vsotf_reference", "zero_piston_tilt")
"""``ModelOptions`` fields that reach the compiled pipeline as static configuration: the
NCSF model and the VSOTF reference select code (the reference also sets the reference
aperture's shape), and zeroing piston and tilt selects which coefficients enter."""


class ModelParameters(eqx.Module):
    """The model's numbers, each a traced leaf (unitless unless stated; shape () or a
    leading batch axis when stacked for ``jax.vmap``).

    Attributes
    ----------
    lca_A : D·nm, constant A of D(λ) = A (1/(λ−c) − 1/(λ_ref−c))
    lca_c_nm : nm, constant c (< 380 nm)
    lca_reference_nm : nm, λ_ref, in focus for zero accommodation error
    sa_slope_um_per_D : µm/D, change of c(4,0) per dioptre of accommodation on the reference
        pupil (Cheng et al. 2004: −0.0435)
    sa_reference_pupil_mm : mm, the pupil on which that slope was measured (> 0)
    sa_gain : 1 with accommodation SA, 0 without (``ModelOptions.accommodation_sa="off"``)
    sa_pupil_exponent : p in (d/d_ref)^p, 4 for the exact rescaling ("scaled"), 0 to add the
        reference pupil's coefficient unchanged ("unscaled", "wavefront_5mm")
    sa_reference_radius_weight : w, the Zernike pupil of that c(4,0) has radius
        ½(d + w (d_ref − d)) mm: 0 the calculation pupil, 1 the reference pupil
        ("wavefront_5mm")
    sce_exponent : e, pupil amplitude 10^(−e·s·ρ r²): 1 "amplitude", 0.5 "intensity", 0 "off"
    sce_rho_scale : s, factor on the ρ(λ) table
    unit_sum : u, each wavelength's weight divided by (its transmitted energy)^u: 0
        "transmitted_energy", 1 "unit_sum"; values between blend the two

    Build it with :meth:`ModelOptions.parameters`; change a value with ``eqx.tree_at`` or
    :meth:`replace` (e.g. ``p.replace(lca_A=jnp.asarray(633.46))``); stack several with
    ``jax.tree.map(lambda *x: jnp.stack(x), *ps)``.
    """

    lca_A: Float[Array, "*batch"] = eqx.field(converter=as_real_array)
    lca_c_nm: Float[Array, "*batch"] = eqx.field(converter=as_real_array)
    lca_reference_nm: Float[Array, "*batch"] = eqx.field(converter=as_real_array)
    sa_slope_um_per_D: Float[Array, "*batch"] = eqx.field(converter=as_real_array)
    sa_reference_pupil_mm: Float[Array, "*batch"] = eqx.field(converter=as_real_array)
    sa_gain: Float[Array, "*batch"] = eqx.field(converter=as_real_array)
    sa_pupil_exponent: Float[Array, "*batch"] = eqx.field(converter=as_real_array)
    sa_reference_radius_weight: Float[Array, "*batch"] = eqx.field(converter=as_real_array)
    sce_exponent: Float[Array, "*batch"] = eqx.field(converter=as_real_array)
    sce_rho_scale: Float[Array, "*batch"] = eqx.field(converter=as_real_array)
    unit_sum: Float[Array, "*batch"] = eqx.field(converter=as_real_array)

    def __check_init__(self):
        # concrete values only: traced ones pass (the host checked what it built them from)
        for name, ok, allowed in (
            ("lca_c_nm", lambda v: v < 380.0, "< 380 nm (below every wavelength)"),
            ("sa_reference_pupil_mm", lambda v: v > 0, "> 0 mm"),
            ("sce_rho_scale", lambda v: v >= 0, ">= 0"),
        ):
            value = getattr(self, name)
            if is_concrete(value) and not np.all(ok(np.asarray(value))):
                raise ValueError(f"ModelParameters.{name} must be {allowed}, got {np.asarray(value)}")

    def replace(self, **changes) -> ModelParameters:
        """A copy with some leaves changed (values converted to arrays)."""
        return dataclasses.replace(self, **changes)


def model_numbers(model: ModelOptions | ModelParameters):
    """The numeric model of either face, as an object with :class:`ModelParameters`' field
    names: Python floats from ``ModelOptions`` (host arithmetic in float64), the array
    leaves themselves from ``ModelParameters`` (traced or not)."""
    if isinstance(model, ModelParameters):
        return model
    if isinstance(model, ModelOptions):
        return types.SimpleNamespace(**model.numbers())
    raise TypeError(f"expected ModelOptions or ModelParameters, got {type(model).__name__}")


def stack_parameters(parameters) -> ModelParameters:
    """Several :class:`ModelParameters` stacked along a new leading axis (for ``jax.vmap``)."""
    parameters = list(parameters)
    if not parameters:
        raise ValueError("stack_parameters needs at least one ModelParameters")
    return ModelParameters(**{
        f.name: jnp.stack([getattr(p, f.name) for p in parameters])
        for f in dataclasses.fields(ModelParameters)
    })


__all__ = [
    "ModelOptions",
    "ModelParameters",
    "stack_parameters",
    "model_numbers",
    "STATIC_CHOICES",
    "SCE_EXPONENTS",
    "ACCOMMODATION_SA_NUMBERS",
    "WAVELENGTH_NORMALISATION_NUMBERS",
    "SCE_FORMS",
    "ACCOMMODATION_SA_FORMS",
    "VSOTF_REFERENCES",
    "NCSF_MODELS",
    "SCE_TABLES",
    "WAVELENGTH_NORMALISATIONS",
]
