"""The optics kernel and the pure pipeline: what ``jit``, ``vmap`` and ``grad`` wrap.

:mod:`~lfjax.kernel.scene` (the pytrees a computation takes whole),
:mod:`~lfjax.kernel.optics` (elemental OTFs of every view through an aberrated eye),
:mod:`~lfjax.kernel.metrics` (the NCSF, VSOTF, Strehl ratio, radial MTF and cut-off) and
:mod:`~lfjax.kernel.pipeline` (one pure function from a scene to retinal metrics). Nothing
here runs host-side checks or planning: that is :mod:`lfjax.vision`'s job.
"""

from lfjax.kernel import metrics, optics, pipeline, scene

__all__ = ["metrics", "optics", "pipeline", "scene"]
