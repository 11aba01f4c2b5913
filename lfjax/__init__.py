"""lfjax: what a human eye sees, and where it focuses, looking at a light-field display.

Wave-optics model (Miyanishi, Sahin & Gotchev) of an ideal integral-imaging light-field
display viewed by a population of aberrated eyes, as pure, jitted, vmapped and
differentiable JAX functions.

The folders are the layers, bottom-up (docs/design.md#layers): :mod:`lfjax.base`
(conventions and maths) → :mod:`lfjax.model` (eyes, options, spectra, layouts) →
:mod:`lfjax.display` (lenslets, panel, display spectra) → :mod:`lfjax.kernel` (the optics
kernel and the pure pipeline) → :mod:`lfjax.planner` → :mod:`lfjax.vision` (through-focus,
peaks, PSFs, images, resolution) → the applications, reached by name
(:mod:`lfjax.layout_opt`, :mod:`lfjax.sweep`, :mod:`lfjax.studies`, :mod:`lfjax.design`,
:mod:`lfjax.reproduce`) → :mod:`lfjax.cli`.

This face offers the calls a user starts with.
"""

# The command line (``lfjax``, ``python -m lfjax.cli``) only, before the imports below (JAX,
# seconds): Ctrl-C while it starts ends it with status 130 and one line, not a traceback
# (lfjax.cli.main then hands Ctrl-C back to Python; a library import changes nothing).
import os as _os
import signal as _signal
import sys as _sys


def _interrupted_while_starting(signum, frame):
    _os.write(2, b"lfjax: interrupted while starting; nothing written\n")
    _os._exit(130)


if ((getattr(_sys, "orig_argv", [])[1:3] == ["-m", "lfjax.cli"]
        or _os.path.basename(_sys.argv[0] if _sys.argv else "") == "lfjax")
        and _signal.getsignal(_signal.SIGINT) is _signal.default_int_handler):
    _signal.signal(_signal.SIGINT, _interrupted_while_starting)

from lfjax._version import __version__ as __version__
from lfjax.base.sampling import AliasingError as AliasingError
from lfjax.base.sampling import Sampling as Sampling
from lfjax.display.lenslets import DisplayOptics as DisplayOptics
from lfjax.display.lenslets import LensletArray as LensletArray
from lfjax.display.panel import Panel as Panel
from lfjax.display.spectra import display_primaries as display_primaries
from lfjax.display.spectra import display_spectrum as display_spectrum
from lfjax.model.eyes import Eyes as Eyes
from lfjax.model.eyes import average_eye as average_eye
from lfjax.model.eyes import make_eyes as make_eyes
from lfjax.model.eyes import sample_eyes as sample_eyes
from lfjax.model.layouts import Layout as Layout
from lfjax.model.layouts import grid_layout as grid_layout
from lfjax.model.layouts import hex_layout as hex_layout
from lfjax.model.layouts import make_layout as make_layout
from lfjax.model.layouts import open_pupil as open_pupil
from lfjax.model.options import ModelOptions as ModelOptions
from lfjax.model.options import ModelParameters as ModelParameters
from lfjax.model.spectral import Spectrum as Spectrum
from lfjax.model.spectral import make_spectrum as make_spectrum
from lfjax.planner.plan import Plan as Plan
from lfjax.planner.plan import plan_sampling as plan_sampling
from lfjax.planner.scene import PlanScene as PlanScene
from lfjax.planner.targets import Targets as Targets
from lfjax.vision.focus import ThroughFocus as ThroughFocus
from lfjax.vision.focus import metrics_at as metrics_at
from lfjax.vision.focus import through_focus as through_focus
from lfjax.vision.focus import through_focus_variants as through_focus_variants
from lfjax.vision.peak_options import PeakOptions as PeakOptions
from lfjax.vision.peaks import Peaks as Peaks
from lfjax.vision.peaks import accommodation_peaks as accommodation_peaks
from lfjax.vision.prepare import States as States
from lfjax.vision.psf import monochromatic_psf as monochromatic_psf
from lfjax.vision.viewing import Viewing as Viewing
from lfjax.vision.psf import polychromatic_otf as polychromatic_otf
