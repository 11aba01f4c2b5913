"""The scene and the eye's focus as pytrees: what the display shows, and where the eye accommodates.

* :class:`Scene` — the display scene seen through the eye's pupil: subaperture centres and
  diameters (mm), the central depth plane (D), rendered depths (D), the calculation pupil
  (mm) and optionally the display's own optics (:class:`lfjax.display.lenslets.DisplayOptics`);
* :class:`Accommodation` — the accommodation states (D), which state each (depth, k) pair
  uses, and the spherical aberration accommodation adds (Cheng et al. 2004, read as
  :class:`lfjax.model.options.ModelOptions` says).

Every float is an array leaf, so ``jax.jit``, ``jax.vmap`` and ``jax.grad`` see them as
data. Both are defined here, below the elemental optics kernel (:mod:`lfjax.kernel.optics`) that
takes them whole, and re-exported by :mod:`lfjax.kernel.pipeline`.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float, Int

from lfjax.base.types import as_index_array
from lfjax.base.types import as_real_array as _real
from lfjax.display.lenslets import DisplayOptics
from lfjax.model.layouts import Layout
from lfjax.model.options import ModelOptions, ModelParameters, model_numbers

# ----------------------------------------------------------------------------- accommodation SA


def _sa_geometry(options: ModelOptions | ModelParameters, pupil_diameter_mm):
    """(scale, radius_mm) so that c(4,0)_applied = slope · a · scale on Z(4,0)(r/radius).

    scale = g (d/d_ref)^p and radius = ½(d + w (d_ref − d)), from the numeric form of
    ``accommodation_sa`` (:data:`lfjax.model.options.ACCOMMODATION_SA_NUMBERS`): "scaled"
    (1, 4, 0), "wavefront_5mm" (1, 0, 1), "unscaled" (1, 0, 0), "off" (0, 0, 0)."""
    n = model_numbers(options)
    ref, exponent = n.sa_reference_pupil_mm, n.sa_pupil_exponent
    if isinstance(exponent, float) and exponent.is_integer():
        exponent = int(exponent)  # x**4 as products (jax's integer_pow), as it always was
    scale = n.sa_gain * (pupil_diameter_mm / ref) ** exponent
    radius = 0.5 * (pupil_diameter_mm + n.sa_reference_radius_weight * (ref - pupil_diameter_mm))
    return scale, radius


def sa_c40_um(accommodation_D, pupil_diameter_mm,
              options: ModelOptions | ModelParameters = ModelOptions()):
    """Accommodation spherical aberration added to c(4,0), µm, on the radius of ``_sa_geometry``."""
    scale, _ = _sa_geometry(options, pupil_diameter_mm)
    return model_numbers(options).sa_slope_um_per_D * accommodation_D * scale


def sa_parameters(options: ModelOptions | ModelParameters, pupil_diameter_mm):
    """(µm of c(4,0) per dioptre of accommodation, radius in mm of that Z(4,0)) as an array.

    Passed to the jitted pipeline as data, so switching the accommodation-SA reading does
    not recompile. From ``ModelOptions`` the numbers are combined on the host in float64;
    from :class:`~lfjax.model.options.ModelParameters` (possibly traced) in its own precision.
    """
    scale, radius = _sa_geometry(options, pupil_diameter_mm)
    slope = model_numbers(options).sa_slope_um_per_D
    return jnp.stack(
        [jnp.asarray(slope * scale, float), jnp.asarray(radius, float)]
    )


# ----------------------------------------------------------------------------- pytrees


class Scene(eqx.Module):
    """The display scene seen through the eye's pupil (all leaves are arrays).

    Attributes
    ----------
    centres_mm : (n_sub, 2) subaperture centres (x, y) in the pupil plane, mm
    diameters_mm : (n_sub,) subaperture diameters, mm (cropped by the pupil)
    cdp_D : () central depth plane of the display, D
    depths_D : (n_depth,) rendered depths, D (0 D = infinity)
    pupil_diameter_mm : () calculation pupil, mm
    display : :class:`lfjax.display.lenslets.DisplayOptics` or None (the paper's ideal display:
        geometric circular subapertures, point emitters)
    """

    centres_mm: Float[Array, "n_sub 2"] = eqx.field(converter=_real)
    diameters_mm: Float[Array, " n_sub"] = eqx.field(converter=_real)
    cdp_D: Float[Array, ""] = eqx.field(converter=_real)
    depths_D: Float[Array, " n_depth"] = eqx.field(converter=_real)
    pupil_diameter_mm: Float[Array, ""] = eqx.field(converter=_real)
    display: DisplayOptics | None = None

    def __check_init__(self):
        if self.centres_mm.ndim < 2 or self.centres_mm.shape[-1] != 2:
            raise ValueError(f"Scene.centres_mm must have shape (n_sub, 2), got {self.centres_mm.shape}")
        if self.diameters_mm.shape[-1:] != self.centres_mm.shape[-2:-1]:
            raise ValueError(
                f"Scene.diameters_mm must have shape ({self.centres_mm.shape[-2]},), "
                f"got {self.diameters_mm.shape}"
            )

    @classmethod
    def from_layout(cls, layout: Layout, depths_D, cdp_D, pupil_diameter_mm,
                    display: DisplayOptics | None = None) -> Scene:
        """Scene of a :class:`~lfjax.model.layouts.Layout` rendering ``depths_D`` (D)."""
        return cls(layout.centres_mm, layout.diameters_mm, cdp_D, jnp.atleast_1d(_real(depths_D)),
                   pupil_diameter_mm, display)

    @property
    def n_depths(self) -> int:
        return int(self.depths_D.shape[-1])


class Accommodation(eqx.Module):
    """Accommodation states and how the eye changes with them.

    Elemental OTFs are computed once per entry of ``states_D`` and shared by every rendered
    depth that uses it (``pair_index``).

    Attributes
    ----------
    states_D : (n_states,) absolute accommodation 1/z_acc, D
    pair_index : (n_depth, n_k) int, the state of each (rendered depth, k) pair
    sa_c40_um_per_D : () change of c(4,0) per dioptre of accommodation on the Zernike
        pupil of radius ``sa_radius_mm``, µm/D (Cheng et al. 2004, as ``ModelOptions`` reads it)
    sa_radius_mm : () radius of that Zernike pupil, mm
    """

    states_D: Float[Array, " n_states"] = eqx.field(converter=_real)
    pair_index: Int[Array, "n_depth n_k"] = eqx.field(converter=as_index_array)
    sa_c40_um_per_D: Float[Array, ""] = eqx.field(converter=_real)
    sa_radius_mm: Float[Array, ""] = eqx.field(converter=_real)

    def __check_init__(self):
        if self.pair_index.ndim < 2:
            raise ValueError(
                f"Accommodation.pair_index must have shape (n_depth, n_k), got {self.pair_index.shape}"
            )

    @classmethod
    def per_depth(cls, accommodation_D, options: ModelOptions | ModelParameters,
                  pupil_diameter_mm) -> Accommodation:
        """States given per rendered depth, (n_depth, n_k) in D: each pair computed on its own.
        ``options``: the accommodation SA's numbers, from ``ModelOptions`` or (traceable)
        ``ModelParameters``."""
        acc = _real(accommodation_D)
        if acc.ndim != 2:
            raise ValueError(f"accommodation_D must have shape (n_depth, n_k), got {acc.shape}")
        index = jnp.arange(acc.size, dtype=jnp.int32).reshape(acc.shape)
        return cls.shared(acc.reshape(-1), index, options, pupil_diameter_mm)

    @classmethod
    def shared(cls, states_D, pair_index, options: ModelOptions | ModelParameters,
               pupil_diameter_mm) -> Accommodation:
        """States ``states_D`` (D) shared by depths through ``pair_index`` (n_depth, n_k);
        ``options`` as in :meth:`per_depth`."""
        sa = sa_parameters(options, _real(pupil_diameter_mm))
        return cls(states_D, pair_index, sa[0], sa[1])


__all__ = [
    "Scene",
    "Accommodation",
    "sa_c40_um",
    "sa_parameters",
]
