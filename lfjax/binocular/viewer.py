"""A viewer: two eyes and the distance between their pupils.

A :class:`Viewer` holds a batch of viewers: ``left`` and ``right`` are :class:`~lfjax.Eyes`
of the same batch size (viewer ``i`` is ``left[i]`` with ``right[i]``) and ``ipd_mm`` their
interpupillary distances. Both eyes' coefficients are in the one frame every lfjax
computation uses (x to the viewer's right, y up, seen from the eye), so each eye enters the
monocular pipeline unchanged; a right eye that mirrors its left eye has the left eye's
coefficients with the modes odd in x negated (:meth:`lfjax.model.eyes.Eyes.mirrored`).
"""

from __future__ import annotations

import math
from functools import lru_cache
from importlib import resources

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.base.types import as_real_array, is_concrete
from lfjax.model.eyes import Eyes


@lru_cache(maxsize=1)
def binocular_statistics() -> dict[str, float]:
    """The published numbers of ``lfjax/data/binocular_statistics.csv`` (quantity → value;
    each row names its unit and source, lfjax/data/README.md)."""
    text = resources.files("lfjax").joinpath("data/binocular_statistics.csv").read_text()
    rows = [line.split(",", 3) for line in text.splitlines()[1:] if line.strip()]
    return {name: float(value) for name, value, _unit, _source in rows}


def ipd_range_mm() -> tuple[float, float]:
    """The interpupillary distances a :class:`Viewer` accepts, mm: 45–80 mm, the range
    Dodgson (2004) found to include (almost) all adults."""
    stats = binocular_statistics()
    return stats["ipd_min_mm"], stats["ipd_max_mm"]


def check_ipd_mm(ipd_mm, parameter: str = "ipd_mm", owner: str | None = "Viewer") -> None:
    """Refuse concrete interpupillary distances that are not finite or lie outside
    :func:`ipd_range_mm` (a :class:`~lfjax.base.errors.ParameterError` naming
    ``parameter``, mm and the range); traced values pass."""
    if not is_concrete(ipd_mm):
        return
    low, high = ipd_range_mm()
    try:
        v = np.asarray(ipd_mm, float)
    except (TypeError, ValueError):
        v = np.asarray(math.nan)
    bad = ~(np.isfinite(v) & (v >= low) & (v <= high))
    if np.any(bad):
        raise ParameterError(
            parameter, "{%s} must lie in [{low:g}, {high:g}] mm (the adult range of Dodgson "
            "2004), got {got}" % parameter, owner=owner, low=low, high=high,
            got=v[bad].ravel().tolist()[:5] if v.ndim else float(v))


class Viewer(eqx.Module):
    """A batch of viewers, each a left eye, a right eye and an interpupillary distance.

    Attributes
    ----------
    left, right : :class:`~lfjax.Eyes` of equal batch size (n_viewers), equal number of
        modes and equal measured pupil; ``left.orientation == "left"`` and
        ``right.orientation == "right"``
    ipd_mm : (n_viewers,) interpupillary distance, mm, in :func:`ipd_range_mm` (45–80 mm);
        a traced leaf (``jax.grad`` applies; checked on the host when concrete)

    Examples
    --------
    >>> import lfjax
    >>> from lfjax.binocular.viewer import Viewer
    >>> v = Viewer.identical(lfjax.average_eye(3.0), ipd_mm=63.0)
    >>> v.n_viewers, float(v.ipd_mm[0])
    (1, 63.0)
    >>> Viewer.identical(lfjax.average_eye(3.0), ipd_mm=30.0)
    Traceback (most recent call last):
    ...
    lfjax.base.errors.ParameterError: Viewer.ipd_mm must lie in [45, 80] mm (the adult range of Dodgson 2004), got 30.0
    """

    left: Eyes
    right: Eyes
    ipd_mm: jnp.ndarray = eqx.field(converter=as_real_array)

    def __check_init__(self):
        for name in ("left", "right"):
            eye = getattr(self, name)
            if not isinstance(eye, Eyes):
                raise ParameterError(
                    name, "{%s} must be lfjax.Eyes (a viewer has two eyes), got {got}" % name,
                    owner="Viewer", got=type(eye).__name__)
            if eye.orientation != name:
                raise ParameterError(
                    name, "{%s} must be in %s-eye orientation (Eyes.orientation), got {got!r}; "
                    "Eyes.mirrored() turns one into the other" % (name, name), owner="Viewer",
                    got=eye.orientation)
        if self.left.n_eyes != self.right.n_eyes:
            raise ParameterError(
                "right", "{left} and {right} must hold one eye per viewer each, got "
                "{n_left} and {n_right} eyes", owner="Viewer", n_left=self.left.n_eyes,
                n_right=self.right.n_eyes)
        if self.left.n_modes != self.right.n_modes:
            raise ParameterError(
                "right", "{left} and {right} must have the same Zernike modes, got {n_left} "
                "and {n_right}", owner="Viewer", n_left=self.left.n_modes,
                n_right=self.right.n_modes)
        if self.left.measured_pupil_mm != self.right.measured_pupil_mm:
            raise ParameterError(
                "right", "{left} and {right} must be measured on one pupil, got {p_left:g} "
                "and {p_right:g} mm", owner="Viewer", p_left=self.left.measured_pupil_mm,
                p_right=self.right.measured_pupil_mm)
        if self.ipd_mm.shape != (self.left.n_eyes,):
            raise ParameterError(
                "ipd_mm", "{ipd_mm} must have shape (n_viewers,) = ({n},) mm, got {got}",
                owner="Viewer", n=self.left.n_eyes, got=self.ipd_mm.shape)
        check_ipd_mm(self.ipd_mm)

    @property
    def n_viewers(self) -> int:
        return self.left.n_eyes

    @property
    def eyes(self) -> tuple[Eyes, Eyes]:
        """(left, right)."""
        return self.left, self.right

    def __getitem__(self, index) -> Viewer:
        """Sub-batch (keeps the batch axis)."""
        ipd = jnp.atleast_1d(self.ipd_mm[index])
        return Viewer(self.left[index], self.right[index], ipd)

    @classmethod
    def identical(cls, eyes: Eyes, ipd_mm=None) -> Viewer:
        """Viewers whose two eyes have the same coefficients as ``eyes`` (one viewer per
        eye): each eye then computes exactly what ``eyes`` computes alone. ``ipd_mm``
        scalar or (n_viewers,), mm; default the adult mean of Dodgson (2004)."""
        return cls._pair(eyes, eyes.zernike_um, ipd_mm)

    @classmethod
    def mirror_pair(cls, eyes: Eyes, ipd_mm=None) -> Viewer:
        """Viewers whose right eye mirrors the left one (enantiomorphism, x → −x): ``eyes``
        is taken in left-eye orientation; the right eye has its modes odd in x negated."""
        left = eyes if eyes.orientation == "left" else eyes.mirrored()
        return cls._pair(left, left.mirrored().zernike_um, ipd_mm)

    @classmethod
    def _pair(cls, eyes: Eyes, right_um, ipd_mm) -> Viewer:
        if not isinstance(eyes, Eyes):
            raise ParameterError("eyes", "{eyes} must be lfjax.Eyes, got {got}",
                                 got=type(eyes).__name__)
        left = eyes if eyes.orientation == "left" else Eyes(
            eyes.zernike_um, eyes.measured_pupil_mm, "left")
        right = Eyes(right_um, eyes.measured_pupil_mm, "right")
        ipd = binocular_statistics()["ipd_mean_mm"] if ipd_mm is None else ipd_mm
        check_ipd_mm(ipd)
        ipd = jnp.broadcast_to(as_real_array(ipd), (eyes.n_eyes,))
        return cls(left, right, ipd)


def check_viewer(viewer, name: str = "viewer") -> Viewer:
    """``viewer`` itself when it is a :class:`Viewer`; else a ParameterError naming ``name``
    (a single :class:`~lfjax.Eyes` is one eye, not a viewer)."""
    if not isinstance(viewer, Viewer):
        hint = (" (one eye is missing: build a pair with Viewer.identical(eyes) or "
                "Viewer.mirror_pair(eyes))" if isinstance(viewer, Eyes) else "")
        raise ParameterError(name, "{%s} must be lfjax.binocular.Viewer (left eye, right eye, "
                             "ipd_mm), got {got}{hint}" % name, got=type(viewer).__name__,
                             hint=hint)
    return viewer


__all__ = ["Viewer", "check_viewer", "check_ipd_mm", "ipd_range_mm", "binocular_statistics"]
