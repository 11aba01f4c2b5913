"""Binocular modelling choices: how the two eyes' focus becomes one accommodation.

:class:`BinocularOptions` is a frozen dataclass beside :class:`lfjax.ModelOptions`, not
fields of it: its choices act after each eye's through-focus and never reach the compiled
monocular pipeline, while ``ModelOptions`` is hashed into the pipeline's configuration and
written, field by field, into every result file — a field added there would change every
stored file of the monocular model for a choice it never reads.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from lfjax.base.errors import ParameterError

COMBINATIONS = ("mean_vsotf", "better_eye", "dominant_eye")
EYES = ("left", "right")
COMFORT_ZONES = ("shibata2011", "percival")


@dataclass(frozen=True)
class BinocularOptions:
    """How one accommodation is predicted for a pair of eyes (consensual accommodation).

    Attributes
    ----------
    combination : str
        ``"mean_vsotf"`` (default): the accommodation state that maximises the mean of the
        two eyes' VSOTF (both eyes' image quality counts equally). ``"better_eye"``: the
        peak of the eye whose peak VSOTF is higher (that eye's focus wins). ``"dominant_eye"``:
        the peak of ``dominant_eye``'s VSOTF.
    dominant_eye : ``"right"`` (default) or ``"left"``; read by ``"dominant_eye"`` only
    ca_c_D_per_prism_D : float
        Convergence-accommodation to convergence ratio, D of accommodation per prism dioptre
        of convergence, in [0, 0.2] (the range Hirani & Firth 2009 measured); 0 (default)
        switches the cross-link off. Their adult mean is 0.13
        (:func:`lfjax.binocular.viewer.binocular_statistics` ``["ca_c_D_per_prism_D"]``).
        With it, the predicted accommodation is
        A = A_blur + CA/C · 100 · p · (V − A_blur) / (1 + G), p the IPD in m, V the vergence
        demand in metre angles and G ``blur_loop_gain``: convergence beyond what A_blur
        would bring pulls accommodation towards the vergence demand, opposed by the blur
        loop with gain G.
    blur_loop_gain : float
        G ≥ 0, unitless: the gain with which blur-driven accommodation opposes the
        cross-link. 0 (default): unopposed, the largest effect the cross-link can have (lfjax
        ships no published value of G).
    comfort_zone : ``"shibata2011"`` (default) or ``"percival"`` (needs the viewer's zone of
        clear single binocular vision, :func:`lfjax.binocular.comfort.percival_zone`)
    """

    combination: str = "mean_vsotf"
    dominant_eye: str = "right"
    ca_c_D_per_prism_D: float = 0.0
    blur_loop_gain: float = 0.0
    comfort_zone: str = "shibata2011"

    def __post_init__(self):
        for name, allowed in (("combination", COMBINATIONS), ("dominant_eye", EYES),
                              ("comfort_zone", COMFORT_ZONES)):
            if getattr(self, name) not in allowed:
                raise ParameterError(name, "{%s} must be one of {allowed}, got {got!r}" % name,
                                     owner="BinocularOptions", allowed=", ".join(allowed),
                                     got=getattr(self, name))
        ratio = self.ca_c_D_per_prism_D
        if not (isinstance(ratio, (int, float)) and 0.0 <= float(ratio) <= 0.2):
            raise ParameterError("ca_c_D_per_prism_D", "{ca_c_D_per_prism_D} must lie in [0, 0.2] "
                                 "D per prism dioptre, got {got!r}", owner="BinocularOptions",
                                 got=ratio)
        gain = self.blur_loop_gain
        if not (isinstance(gain, (int, float)) and 0.0 <= float(gain) <= 1e3):
            raise ParameterError("blur_loop_gain", "{blur_loop_gain} must lie in [0, 1000] "
                                 "(unitless), got {got!r}", owner="BinocularOptions", got=gain)

    def replace(self, **changes) -> BinocularOptions:
        """A copy with some fields changed."""
        return dataclasses.replace(self, **changes)

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


__all__ = ["BinocularOptions", "COMBINATIONS", "COMFORT_ZONES"]
