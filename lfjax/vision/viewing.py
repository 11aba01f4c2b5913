"""How the eye views the display: the viewing conditions every vision entry point takes.

A :class:`Viewing` is one small frozen object checked when it is built, the way diffrax's
``SaveAt`` or ``PIDController`` is: the calculation pupil, the display's central depth plane
and the display's optics travel together instead of as three keywords threaded through
every signature. A new viewing condition is a new field here, not a new keyword on every
entry point.

Fields that later viewing conditions add belong here too (a gaze direction, a pair of eyes):
:func:`~lfjax.vision.prepare.prepare` is the one place that reads a ``Viewing``.
"""

from __future__ import annotations

import math

import equinox as eqx
import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.base.types import is_concrete
from lfjax.base.units import check_dioptres
from lfjax.display.lenslets import DisplayOptics

MAX_PUPIL_MM = 10.0
"""Largest calculation pupil a :class:`Viewing` accepts, mm (the dilated human pupil is
under about 9 mm; each computation also refuses a pupil above the eyes' measured one)."""

MAX_PUPIL_OFFSET_MM = 30.0
"""Largest pupil displacement a :class:`Viewing` accepts along each axis, mm (half the
widest eye box of the presets, the phone panel's ~50 mm, with room to map past its edge).
Each computation also refuses a displacement that leaves a view of its layout entirely
outside the moved pupil."""


class Viewing(eqx.Module):
    """The viewing conditions of one computation.

    Attributes
    ----------
    pupil_diameter_mm : the calculation pupil, mm, in (0, :data:`MAX_PUPIL_MM`]; each
        computation also requires it ≤ the eyes' measured pupil. May be traced (then
        checked where it is used).
    cdp_D : the display's central depth plane (where its image plane lies), D, in the
        model's range [0, 10] D. May be traced.
    display : :class:`~lfjax.display.lenslets.DisplayOptics` of a real display (lenslet
        diffraction and aberrations, finite pixels, strips), or None for the paper's ideal
        display.
    pupil_offset_mm : (x, y), mm, each in [−:data:`MAX_PUPIL_OFFSET_MM`,
        +:data:`MAX_PUPIL_OFFSET_MM`]: the eye's pupil displaced from the design position
        in the display's frame, gaze straight ahead (eye box and pupil swim). +x is to the
        viewer's right and +y up, as the layout's centres are: a pupil moved by Δ sees
        every view at ``centre − Δ`` in its own coordinates, cropped by the moved pupil
        (:func:`~lfjax.vision.prepare.prepare`). Default (0, 0): the design position, today's
        numbers bit for bit. Ignored for natural viewing (no layout: a real point, no views).
        May be traced (differentiable; then not checked on the host).

    A ``Viewing`` is a pytree (an ``equinox.Module``), so a function of a traced pupil or CDP
    can build one inside ``jax.grad`` or ``jax.vmap``.

    Examples
    --------
    >>> import lfjax
    >>> lfjax.Viewing(pupil_diameter_mm=4.0, cdp_D=1.5).cdp_D
    1.5
    >>> lfjax.Viewing(cdp_D=-1.0)
    Traceback (most recent call last):
    ...
    lfjax.base.errors.ParameterError: cdp_D: every CDP must lie in the model's range [0, 10] D ...
    """

    pupil_diameter_mm: float = 3.0
    cdp_D: float = 2.0
    display: DisplayOptics | None = None
    pupil_offset_mm: tuple = (0.0, 0.0)

    def __check_init__(self):
        pupil = self.pupil_diameter_mm
        if is_concrete(pupil):
            try:
                value = float(pupil)
            except (TypeError, ValueError):
                value = math.nan
            if not (0 < value <= MAX_PUPIL_MM):
                raise ParameterError(
                    "pupil_diameter_mm", "{pupil_diameter_mm} must lie in (0, {top:g}] mm, "
                    "got {got!r}", owner="Viewing", top=MAX_PUPIL_MM, got=pupil)
        if is_concrete(self.cdp_D):
            check_dioptres("cdp_D", self.cdp_D, "CDP")
        if self.display is not None and not isinstance(self.display, DisplayOptics):
            raise ParameterError(
                "display", "{display} must be lfjax.display.lenslets.DisplayOptics or None "
                "(e.g. LensletArray.optics()), got {got}", owner="Viewing",
                got=type(self.display).__name__)
        _check_offset(self.pupil_offset_mm)


def _check_offset(offset) -> None:
    """Host check of a concrete ``pupil_offset_mm``: two finite numbers, mm, within
    ±:data:`MAX_PUPIL_OFFSET_MM`."""
    if not is_concrete(offset):
        return
    try:
        value = np.asarray(offset, float)
    except (TypeError, ValueError):
        value = np.full(0, math.nan)
    if value.shape != (2,) or not np.all(np.abs(value) <= MAX_PUPIL_OFFSET_MM):
        raise ParameterError(
            "pupil_offset_mm", "{pupil_offset_mm} must be (x, y) in mm, each in "
            "[-{top:g}, {top:g}] mm, got {got!r}", owner="Viewing", top=MAX_PUPIL_OFFSET_MM,
            got=offset)


def check_viewing(viewing) -> Viewing:
    """``viewing`` itself when it is a :class:`Viewing`; else a
    :class:`~lfjax.base.errors.ParameterError` naming ``viewing`` (before any work)."""
    if not isinstance(viewing, Viewing):
        raise ParameterError("viewing", "{viewing} must be lfjax.Viewing (pupil_diameter_mm, "
                             "cdp_D, display), got {got}", got=type(viewing).__name__)
    return viewing


__all__ = ["Viewing", "MAX_PUPIL_MM", "MAX_PUPIL_OFFSET_MM", "check_viewing"]
