"""What the eye resolves of a display: its optical cut-off capped by the display's sampling.

The optical cut-off comes from the eye's MTF (:func:`lfjax.kernel.metrics.cutoff_frequency`);
the sampling limit from the panel's geometry (:func:`lfjax.display.panel.sampling_limit_cpd`).
It lives here, above both, because it reads a through-focus result.
"""

from __future__ import annotations

import jax.numpy as jnp

from lfjax.display.panel import Panel, sampling_limit_cpd
from lfjax.kernel.metrics import cutoff_frequency


def perceivable_cutoff_cpd(radial_mtf, frequencies_cpd, panel: Panel, depths_D,
                           threshold: float = 0.05):
    """What the eye resolves of a scene at ``depths_D`` on ``panel``: the lower of its
    optical cut-off and the display's sampling limit, cpd.

    ``radial_mtf`` (…, n_depth, n_freq) is the eye's radial MTF at its predicted
    accommodation for each rendered depth (e.g.
    :meth:`lfjax.vision.focus.ThroughFocus.mtf_at_peak`), computed with the panel's
    :meth:`~lfjax.display.panel.Panel.optics` and layout, on ``frequencies_cpd`` (n_freq,); ``depths_D``
    (n_depth,) the rendered depths, D. The optical cut-off is read where the MTF first
    falls to ``threshold`` (the paper's 0.05, :func:`lfjax.kernel.metrics.cutoff_frequency`).

    The model and why. The MTF already holds both apertures of the display's samples:
    each pixel's emitter (:class:`~lfjax.display.lenslets.DisplayOptics`' pixel blur) and each
    lenslet's aperture (a view's defocus blur, M·a·|D − D_c|, which is the transfer of the
    lenslet aperture seen from the eye, plus its diffraction). What the MTF cannot hold is
    the sampling itself: detail above the Nyquist frequency of the samples does not blur,
    it aliases. So the perceivable cut-off is the MTF's cut-off capped at the sampling
    limit :func:`~lfjax.display.panel.sampling_limit_cpd` — the sampled-imaging-system reading of resolution
    (Boreman 2001, ch. 4: the system MTF includes the sampling apertures, and the Nyquist
    frequency bounds the resolvable band). Multiplying the MTF by another aperture sinc
    would count the lenslet aperture twice.

    Limits: a lenslet pitch much larger than the eye's resolution → the lenslet Nyquist
    frequency (off the CDP); tiny lenslets and pixels → the optical cut-off. The bound is
    the pinhole-viewer one of the sampling analyses cited: an eye whose pupil holds several
    views sums sample grids shifted by their parallax, which may carry some detail beyond
    it; this function does not model that. Returns (…, n_depth) cpd.

    Reference: G. D. Boreman, *Modulation Transfer Function in Optical and
    Electro-Optical Systems*, SPIE Press (2001), ch. 4.
    """
    if not (0.0 < float(threshold) < 1.0):
        raise ValueError(f"threshold must be in (0, 1) (an MTF level), got {threshold}")
    optical = cutoff_frequency(jnp.asarray(radial_mtf), jnp.asarray(frequencies_cpd), threshold)
    return jnp.minimum(optical, sampling_limit_cpd(panel, depths_D))


def perceivable_cutoff_at_peak(tf, panel: Panel, metric: str = "vsotf", threshold: float = 0.05):
    """:func:`perceivable_cutoff_cpd` of a :class:`~lfjax.vision.focus.ThroughFocus`
    computed for ``panel`` (its layout and :meth:`~lfjax.display.panel.Panel.optics`): the radial MTF at each
    eye's predicted accommodation (the grid peak of ``metric``) against the sampling limit
    of each rendered depth. Returns (n_eyes, n_depth) cpd."""
    return perceivable_cutoff_cpd(tf.mtf_at_peak(metric), tf.radial_freq_cpd, panel,
                                  jnp.asarray(tf.depths_D), threshold)
