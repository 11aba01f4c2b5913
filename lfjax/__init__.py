"""lfjax: what a human eye sees, and where it focuses, looking at a light-field display.

Wave-optics model (Miyanishi, Sahin & Gotchev) of an ideal integral-imaging light-field
display viewed by a population of aberrated eyes, as pure, jitted, vmapped and
differentiable JAX functions. Stage modules: :mod:`lfjax.zernike`, :mod:`lfjax.eyes`,
:mod:`lfjax.spectral`, :mod:`lfjax.layouts`, :mod:`lfjax.apertures`, :mod:`lfjax.scene`,
:mod:`lfjax.optics` (the elemental optics kernel), :mod:`lfjax.metrics`,
:mod:`lfjax.pipeline` (the pure core), :mod:`lfjax.psf`, :mod:`lfjax.through_focus`,
:mod:`lfjax.images`, :mod:`lfjax.planner`, :mod:`lfjax.peaks`, :mod:`lfjax.layout_opt`;
beyond the paper's ideal display: :mod:`lfjax.display` (lenslet diffraction, pixels),
:mod:`lfjax.display_spectra` (display spectra), :mod:`lfjax.display_effects` (the study),
:mod:`lfjax.panel` (a display as built) and :mod:`lfjax.design` (fitting one to eyes);
:mod:`lfjax.reproduce` and :mod:`lfjax.cli` run the paper's study. The layers they form,
bottom-up, are in docs/design.md#layers.
"""

from . import display as display
from . import display_spectra as display_spectra
from . import eyes as eyes
from . import layout_opt as layout_opt
from . import layouts as layouts
from . import metrics as metrics
from . import optics as optics
from . import panel as panel
from . import peaks as peaks
from . import pipeline as pipeline
from . import planner as planner
from . import psf as psf
from . import spectral as spectral
from . import through_focus as through_focus
from . import units as units
from . import zernike as zernike
from ._version import __version__ as __version__
from .display import DisplayOptics as DisplayOptics
from .display import LensletArray as LensletArray
from .eyes import Eyes as Eyes
from .eyes import average_eye as average_eye
from .eyes import sample_eyes as sample_eyes
from .layouts import grid_layout as grid_layout
from .layouts import hex_layout as hex_layout
from .layouts import make_layout as make_layout
from .layouts import open_pupil as open_pupil
from .options import ModelOptions as ModelOptions
from .options import ModelParameters as ModelParameters
from .panel import Panel as Panel
from .psf import monochromatic_psf as monochromatic_psf
from .psf import polychromatic_otf as polychromatic_otf
from .sampling import AliasingError as AliasingError
from .sampling import Sampling as Sampling
from .spectral import make_spectrum as make_spectrum
