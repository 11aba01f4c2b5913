"""The eyes of a fit and of its held-out report, drawn in one place: the training eyes from
a seed, the held-out eyes from the next seed, and the provenance that names them.

Both the layout optimiser (:func:`lfjax.layout_opt.optimise_and_save`) and the display
design (``lfjax design``, :mod:`lfjax.design`) draw their eyes with :class:`EyeDraw`, so
the two seeds and the provenance keys are decided here once.

Part of :mod:`lfjax.layout_opt` (its public names are re-exported there)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.model.eyes import Eyes, sample_eyes

MEASURED_PUPIL_MM = 3.0
"""The pupil (mm) of the Thibos et al. (2002) fit the eyes are drawn from
(:func:`lfjax.model.eyes.sample_eyes`): the calculation pupil can be no larger."""

EYE_DRAW_KEYS = ("seed_train", "n_train_eyes", "seed_test", "n_test_eyes")
"""The provenance keys of an eye draw (:meth:`EyeDraw.provenance`), in order."""


def whole_number(name: str, value, lowest: int, below: int | None = None) -> int:
    """``value`` as an int when it is a whole number in [``lowest``, ``below``); else a
    :class:`~lfjax.base.errors.ParameterError` naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lowest or (
            below is not None and value >= below):
        top = f" and < {below}" if below is not None else ""
        raise ParameterError(name, "{%s} must be a whole number >= {lowest}{top}, got {got!r}" % name,
                             lowest=lowest, top=top, got=value)
    return int(value)


@dataclass(frozen=True)
class EyeDraw:
    """Which virtual eyes a fit and its report use, checked when made (a
    :class:`~lfjax.base.errors.ParameterError` names the field).

    Attributes
    ----------
    seed : seed of the training eyes, a whole number in [0, 2³²); the held-out eyes are
        drawn from ``seed + 1``, so the two populations never share an eye's draw
    train_eyes : training eyes, ≥ 1
    test_eyes : held-out eyes, ≥ 0 (0: none; the report is then on the training eyes)
    """

    seed: int = 0
    train_eyes: int = 10
    test_eyes: int = 20

    def __post_init__(self):
        whole_number("train_eyes", self.train_eyes, 1)
        whole_number("test_eyes", self.test_eyes, 0)
        whole_number("seed", self.seed, 0, 2**32)

    @property
    def held_out(self) -> bool:
        """Whether there are held-out eyes (``test_eyes`` ≥ 1)."""
        return self.test_eyes > 0

    def train(self) -> Eyes:
        """The training eyes: ``train_eyes`` eyes from ``seed``, measured on
        :data:`MEASURED_PUPIL_MM`."""
        return sample_eyes(self.seed, self.train_eyes, MEASURED_PUPIL_MM)

    def test(self) -> Eyes | None:
        """The held-out eyes: ``test_eyes`` eyes from ``seed + 1`` (None without any)."""
        return sample_eyes(self.seed + 1, self.test_eyes, MEASURED_PUPIL_MM) if self.held_out else None

    def report(self) -> Eyes:
        """The eyes a report scores: the held-out ones, or the training ones without them."""
        return self.test() if self.held_out else self.train()

    def provenance(self) -> dict:
        """The draw as provenance (:data:`EYE_DRAW_KEYS`): each population's seed (None for
        no held-out eyes) and size."""
        return {"seed_train": int(self.seed), "n_train_eyes": int(self.train_eyes),
                "seed_test": int(self.seed) + 1 if self.held_out else None,
                "n_test_eyes": int(self.test_eyes)}


def planning_eyes(train: Eyes, test: Eyes | None) -> Eyes:
    """The eyes a sampling is planned for: the training and the held-out eyes together (the
    training eyes alone without held-out ones), so that one sampling holds for the fit and
    its report."""
    if test is None:
        return train
    return Eyes(np.concatenate([np.asarray(train.zernike_um), np.asarray(test.zernike_um)]),
                train.measured_pupil_mm)


__all__ = ["MEASURED_PUPIL_MM", "EYE_DRAW_KEYS", "EyeDraw", "planning_eyes", "whole_number"]
