"""Both eyes: viewers, what each eye receives, one accommodation for the pair, and the
vergence–accommodation conflict against the zone of comfort (issue #53).

Modules: :mod:`~lfjax.binocular.viewer` (a viewer is two eyes and an IPD),
:mod:`~lfjax.binocular.population` (seeded viewers from published statistics),
:mod:`~lfjax.binocular.geometry` (vergence demand, conventions),
:mod:`~lfjax.binocular.options` (the binocular modelling choices),
:mod:`~lfjax.binocular.displays` (natural viewing, stereo, near-eye light field, a panel seen by both eyes),
:mod:`~lfjax.binocular.focus` (both eyes' through-focus and the conflict),
:mod:`~lfjax.binocular.comfort` (Shibata et al. 2011 and Percival's zones).
"""

from lfjax.binocular.displays import NaturalViewing, NearEyeDisplay, PanelDisplay, StereoDisplay
from lfjax.binocular.focus import BinocularFocus, binocular_through_focus, pair_metrics_at
from lfjax.binocular.options import BinocularOptions
from lfjax.binocular.population import sample_viewers
from lfjax.binocular.viewer import Viewer

__all__ = ["Viewer", "sample_viewers", "BinocularOptions", "NaturalViewing", "StereoDisplay",
           "NearEyeDisplay", "PanelDisplay", "BinocularFocus", "binocular_through_focus", "pair_metrics_at"]
