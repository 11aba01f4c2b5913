"""The scene a sampling plan is for: :class:`PlanScene`, checked when built.

A plan depends on the scene alone (and on its targets, :class:`lfjax.planner.targets.Targets`):
the layout of views, the calculation pupil, the CDP, the (accommodation, depth) pairs the
computation will evaluate, the spectrum (given, or a range whose step the planner chooses),
the eyes (their ray angles widen the field, their RMS per Zernike order sets the order
kept), the model options and a real display's optics. The planner's proxy
(:mod:`lfjax.planner.proxy`) reads the scene's views grouped by the square's symmetries
(:meth:`PlanScene.view_groups`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from lfjax.display.lenslets import DisplayOptics
from lfjax.display.lenticular import check_display_for_layout
from lfjax.model.eyes import Eyes
from lfjax.model.layouts import Layout, open_pupil
from lfjax.model.options import ModelOptions

# The square's symmetries as maps of (x, y): identity first, then mirrors and quarter turns.
SQUARE_SYMMETRIES = [np.array(m, float) for m in (
    [[1, 0], [0, 1]], [[-1, 0], [0, 1]], [[1, 0], [0, -1]], [[-1, 0], [0, -1]],
    [[0, 1], [1, 0]], [[0, -1], [1, 0]], [[0, 1], [-1, 0]], [[0, -1], [-1, 0]],
)]


def map_psf(psf: np.ndarray, m: np.ndarray) -> np.ndarray:
    """PSF(s) (…, n, n) [y, x] with zero angle at index n//2, mapped by the symmetry ``m``:
    out(θ) = psf(m⁻¹θ), exactly on the grid (indices wrap like the periodic field)."""
    n = psf.shape[-1]
    k = np.arange(n) - n // 2
    ky, kx = np.meshgrid(k, k, indexing="ij")
    inv = np.rint(np.linalg.inv(m)).astype(int)
    sx = inv[0, 0] * kx + inv[0, 1] * ky
    sy = inv[1, 0] * kx + inv[1, 1] * ky
    return psf[..., (sy + n // 2) % n, (sx + n // 2) % n]


def _scene_pairs(depths, accommodation_D, window_D):
    depths = np.atleast_1d(np.asarray(depths, float))
    if accommodation_D is not None:
        grid = np.atleast_1d(np.asarray(accommodation_D, float))
        if grid.size == 2 and window_D is None:  # (lowest, highest) absolute range
            grid = np.linspace(grid[0], grid[1], max(int(round(abs(grid[1] - grid[0]) / 0.2)) + 1, 2))
        acc, dep = np.meshgrid(grid, depths)
        keep = np.ones(acc.shape, bool) if window_D is None else np.abs(acc - dep) <= window_D + 1e-9
        if not np.all(keep.any(axis=1)):
            raise ValueError(f"accommodation_window_D={window_D} leaves no state for some depths")
        return acc[keep], dep[keep]
    w = 1.0 if window_D is None else float(window_D)
    offsets = np.linspace(-w, w, 2 * max(int(math.ceil(w / 0.1)), 1) + 1)
    acc = depths[:, None] + offsets[None, :]
    dep = np.broadcast_to(depths[:, None], acc.shape)
    keep = acc >= -1e-9  # hyperopic limit
    return np.clip(acc[keep], 0.0, None), dep[keep]


@dataclass(frozen=True, eq=False)
class PlanScene:
    """The scene a plan is for, in the units of its names; checked when built.

    Attributes
    ----------
    layout : the views (default: the open pupil of ``pupil_diameter_mm``)
    pupil_diameter_mm : calculation pupil, mm, in (0, 10]
    cdp_D : the display's central depth plane, D
    depths_D : rendered depths, D
    accommodation_D : absolute accommodation states (array, D), or a (lowest, highest) range
        in D (0.2 D steps) when ``accommodation_window_D`` is None; with
        ``accommodation_window_D`` only states within that many dioptres of a depth count (as
        :func:`lfjax.vision.focus.through_focus`). Without ``accommodation_D``: states
        depth ± ``accommodation_window_D`` (hyperopic limit 0 D).
    accommodation_window_D : see ``accommodation_D``, D
    pairs : (accommodation_D, depths_D) arrays of the exact pairs to plan for, D; replaces
        the pairs ``depths_D``/``accommodation_D``/``accommodation_window_D`` describe
    wavelengths_nm : the spectrum to use as given, nm; None: the planner chooses the step over
        ``wavelength_range_nm`` (or uses :attr:`lfjax.planner.targets.Overrides.wavelength_step_nm`)
    wavelength_range_nm : (first, last) nm of a spectrum whose step is planned
    spectral_weights : weights of ``wavelengths_nm`` when they are not V(λ)'s (a display's
        spectrum, :mod:`lfjax.display.spectra`): the guard then leaves out the wavelengths
        this spectrum weighs least, not V(λ)'s
    eyes : the :class:`~lfjax.model.eyes.Eyes` planned for (their ray angles widen the field;
        their RMS per order sets the Zernike order), or None (aberration-free)
    options : :class:`~lfjax.model.options.ModelOptions` (LCA, SCE, NCSF and VSOTF reference
        as the computation uses them)
    display : :class:`~lfjax.display.lenslets.DisplayOptics` of a real display (lenslet
        diffraction, pixels): the field guard adds their blur and the proxy models them as
        the pipeline does; None: the paper's ideal display

    Derived when built: ``pair_acc`` and ``pair_depth``, (n_pairs,) D, every evaluated pair.
    """

    layout: Layout | None = None
    pupil_diameter_mm: float = 3.0
    cdp_D: float = 2.0
    depths_D: object = (2.0,)
    accommodation_D: object = None
    accommodation_window_D: float | None = 1.0
    pairs: tuple | None = None
    wavelengths_nm: object = None
    wavelength_range_nm: tuple[float, float] = (400.0, 700.0)
    spectral_weights: object = None
    eyes: Eyes | None = None
    options: ModelOptions = ModelOptions()
    display: DisplayOptics | None = None
    pair_acc: np.ndarray = field(init=False, repr=False)
    pair_depth: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        pupil = self.pupil_diameter_mm
        if not (0 < pupil <= 10):
            raise ValueError(f"pupil_diameter_mm must be in (0, 10] mm, got {pupil}")
        object.__setattr__(self, "pupil_diameter_mm", float(pupil))
        object.__setattr__(self, "cdp_D", float(self.cdp_D))
        if self.eyes is not None and not isinstance(self.eyes, Eyes):
            raise ValueError(f"eyes must be lfjax.Eyes or None, got {type(self.eyes).__name__}")
        if self.wavelengths_nm is None:
            lo, hi = map(float, self.wavelength_range_nm)
            if not (hi > lo):
                raise ValueError(
                    f"wavelength_range_nm must be increasing, got {self.wavelength_range_nm}")
            if self.spectral_weights is not None:
                raise ValueError("spectral_weights needs wavelengths_nm (the wavelengths they weigh)")
        if self.layout is None:
            object.__setattr__(self, "layout", open_pupil(self.pupil_diameter_mm))
        check_display_for_layout(self.display, self.layout)
        if self.pairs is None:
            pair_acc, pair_depth = _scene_pairs(self.depths_D, self.accommodation_D,
                                                self.accommodation_window_D)
        else:
            pair_acc, pair_depth = (np.asarray(x, float).reshape(-1) for x in self.pairs)
        if np.any(pair_acc < -1e-9) or np.any(pair_depth < 0):
            raise ValueError("accommodation and depths must be >= 0 D")
        object.__setattr__(self, "pair_acc", pair_acc)
        object.__setattr__(self, "pair_depth", pair_depth)

    @property
    def pupil_mm(self) -> float:
        """The calculation pupil, mm (``pupil_diameter_mm``)."""
        return self.pupil_diameter_mm

    @property
    def eyes_zernike_um(self):
        """The eyes' coefficients (n_eyes, n_modes) µm on their measured pupil, or None."""
        return None if self.eyes is None else np.asarray(self.eyes.zernike_um)

    @property
    def measured_pupil_mm(self) -> float:
        """The pupil the eyes were measured on, mm (3 mm without eyes: unused then)."""
        return 3.0 if self.eyes is None else self.eyes.measured_pupil_mm

    @property
    def diffracts(self) -> bool:
        return self.display is not None and self.display.diffracts

    @property
    def window_mm(self) -> float:
        """The static window the pipeline sizes its transforms for (the pupil when lenslet
        diffraction spreads the beams)."""
        return self.pupil_mm if self.diffracts else float(self.layout.window_diameter_mm)

    @property
    def accommodation(self) -> np.ndarray:
        """Each evaluated accommodation state once, D."""
        return np.unique(self.pair_acc)

    def view_groups(self) -> list[tuple[tuple[np.ndarray, float], list[np.ndarray]]]:
        """Views grouped by congruence under the square's symmetries: [((centre mm,
        diameter mm) of the group's representative, [2×2 integer matrix M per member]), …],
        each member's centre being M·(representative's centre).

        A member's whole configuration (clipped aperture, SCE, defocus, accommodation SA,
        display shift, all radial or ∝ the centre) is the representative's mapped by M, so
        its PSF is the representative's mapped by M, and — the NCSF being invariant under
        these mirrors and quarter turns — its VSOTF term equals the representative's.
        Views related only by other rotations (a hexagon's 60°) form groups of their own.
        """
        centres = np.asarray(self.layout.centres_mm, float).reshape(-1, 2)
        diam = np.asarray(self.layout.diameters_mm, float).reshape(-1)
        tol = 1e-9 * max(self.pupil_mm, 1.0)
        groups: list = []
        for c, d in zip(centres, diam):
            for (rep, rep_d), maps in groups:
                if abs(rep_d - d) > tol:
                    continue
                m = next((m for m in SQUARE_SYMMETRIES if np.allclose(m @ rep, c, atol=tol)), None)
                if m is not None:
                    maps.append(m)
                    break
            else:
                groups.append(((c, float(d)), [SQUARE_SYMMETRIES[0]]))
        return groups

    @property
    def largest_diameter_mm(self) -> float:
        """Largest beam in the pupil, mm (the pupil when diffraction spreads the beams)."""
        if self.diffracts:
            return self.pupil_mm
        d = np.minimum(np.asarray(self.layout.diameters_mm, float), self.pupil_mm)
        return float(d.max())

    @property
    def smallest_diameter_mm(self) -> float:
        d = np.minimum(np.asarray(self.layout.diameters_mm, float), self.pupil_mm)
        return float(d.min())


__all__ = ["PlanScene", "SQUARE_SYMMETRIES", "map_psf"]
