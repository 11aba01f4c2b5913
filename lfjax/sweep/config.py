"""A population sweep's configuration: read from TOML, validated whole before any compute.

:class:`SweepConfig` names the population (eyes, seed, pupils), the display (layouts, CDP,
rendered depths), the accommodation grid, the spectrum, the sampling, the metrics, the model
options and the chunk size. :func:`load_config` reads a TOML file; :func:`config_from_dict`
takes the same structure as a dict. Every problem found (unknown keys, values of the wrong
type or unit, impossible ranges) is collected and raised once as :class:`SweepConfigError`,
one line per problem, so a user fixes the file in one pass.

Units are part of the key names (``_D`` dioptres, ``_mm`` millimetres, ``_nm`` nanometres,
``_cpd`` cycles per degree); a key with another unit suffix is reported as unknown with the
key it probably meant.
"""

from __future__ import annotations

import dataclasses
import difflib
import json
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lfjax.display.lenslets import DisplayOptics, display_optics_at
from lfjax.display.spectra import DISPLAY_NAMES
from lfjax.model.eyes import THIBOS_PUPILS_MM
from lfjax.model.layout_files import load_layout_json
from lfjax.model.layouts import PAPER_LAYOUTS
from lfjax.model.options import ModelOptions
from lfjax.vision.peaks import METRICS, PEAK_METHODS

CONFIG_FORMAT = "lfjax-sweep/1"

MIN_PUPIL_MM = 2.0
"""Smallest calculation pupil a sweep accepts, mm: the human pupil constricts to about 2 mm
in bright light; below it every eye is nearly diffraction-limited and the through-focus
curves lose the peak that predicts accommodation."""
MIN_WAVELENGTH_STEP_NM = 1.0
"""Finest wavelength step, nm: the CIE 2008 luminous-efficiency data are tabulated at 1 nm."""
MAX_ACCOMMODATION_STATES = 10_000
"""Most accommodation states on the grid (0.0005 D steps over 5 D); the store holds every
state for every eye, and continuous peaks refine off the grid."""


class SweepConfigError(ValueError):
    """A sweep configuration with one or more problems (``problems``: one string each)."""

    def __init__(self, problems: list[str], source: str = "sweep config"):
        self.problems = list(problems)
        lines = "\n".join(f"  - {p}" for p in self.problems)
        super().__init__(f"{source}: {len(self.problems)} problem(s):\n{lines}")


def _grid(start: float, stop: float, step: float) -> np.ndarray:
    n = int(math.floor((stop - start) / step + 1e-9)) + 1
    return np.round(start + step * np.arange(n), 9)


@dataclass(frozen=True)
class SweepConfig:
    """Everything a sweep computes (defaults: the paper's scene on 1,000 eyes).

    Population
    ----------
    n_eyes : virtual eyes drawn from Thibos et al. (2002), ``sample_eyes(seed, n_eyes)``
    seed : seed of the draw, 0 ≤ seed < 2³²
    measured_pupil_mm : which Thibos fit to sample (3.0, 4.5, 6.0 or 7.5 mm); the eyes are
        evaluated inside every pupil of ``pupil_diameters_mm`` (each ≤ this). Default: the
        smallest fit that holds the largest pupil.
    pupil_diameters_mm : calculation pupils, mm
    average_eye : append the Thibos average eye (of the measured pupil) as one more eye,
        flagged ``is_average`` (claims 4 and 5 compare against it)

    Display
    -------
    layouts : names from ``lfjax.model.layouts.PAPER_LAYOUTS`` (sized to each pupil) or paths of
        layout JSON files written by ``lfjax optimise`` (fixed in mm; relative paths are
        relative to the config file)
    cdp_D : central depth plane, D
    depth_offsets_D : rendered depths relative to the CDP, D (natural view: the CDP only)
    lenslet_distance_mm : a lenslet-array display at this distance from the eye (mm): each
        view is its lenslet's Fresnel pattern (:func:`lfjax.display.lenslets.display_optics_at`);
        None: the paper's ideal display
    pixel_width_arcmin : angular width of the emitters, arcmin (0: points)

    Accommodation
    -------------
    accommodation_step_D, accommodation_max_D : absolute grid 0 … max, D
    window_D : each depth is evaluated within ±window_D of it, D

    Spectrum and sampling
    ---------------------
    wavelengths_nm : (start, stop, step), nm; or (start, stop): the step is planned
        (:func:`lfjax.sweep.compute.sweep_spectrum`): the coarsest whose proxy peaks stay
        within ``peak_tolerance_D`` and cut-offs within ``cutoff_tolerance_cpd`` in every
        (pupil, layout) of the sweep (default; 25 nm for the paper's scene)
    display_spectrum : a built-in display's white (:data:`lfjax.display.spectra.DISPLAY_NAMES`)
        weighted by V(λ) on the wavelengths that carry it, instead of V(λ) white on
        ``wavelengths_nm`` (whose step then sets the cell width); None: V(λ) white
    freq_step_cpd : frequency step of the OTF grid, cpd; None: planned per (pupil, layout)
        by :func:`lfjax.planner.plan.plan_sampling` on the whole population
    vsotf_tolerance : with a planned step: the planner's VSOTF accuracy target (its proxy
        runs, seconds per layout); None: its field guard alone (milliseconds)
    peak_tolerance_D, cutoff_tolerance_cpd : targets of a planned wavelength step (D, cpd)

    Metrics
    -------
    continuous_peaks : metrics whose peak is refined off the grid (``lfjax.vision.peaks``)
    peak_method : refinement method (``lfjax.vision.peaks.PEAK_METHODS``)
    cutoff_threshold : MTF value defining the cut-off frequency
    dof_fraction : depth of field fraction (claim 6; the report's population claims)

    Run
    ---
    chunk_size : eyes per compiled call (memory grows linearly with it); a multiple of the
        number of local devices when sharded
    options : :class:`lfjax.ModelOptions`
    """

    n_eyes: int = 1000
    seed: int = 0
    measured_pupil_mm: float | None = None
    pupil_diameters_mm: tuple[float, ...] = (3.0,)
    average_eye: bool = True
    layouts: tuple[str, ...] = PAPER_LAYOUTS
    cdp_D: float = 2.0
    depth_offsets_D: tuple[float, ...] = tuple(float(x) for x in _grid(-2.0, 2.0, 0.5))
    lenslet_distance_mm: float | None = None
    pixel_width_arcmin: float = 0.0
    accommodation_step_D: float = 0.2
    accommodation_max_D: float = 5.0
    window_D: float = 2.0
    wavelengths_nm: tuple[float, ...] = (400.0, 700.0)
    display_spectrum: str | None = None
    freq_step_cpd: float | None = None
    vsotf_tolerance: float | None = None
    peak_tolerance_D: float = 0.01
    cutoff_tolerance_cpd: float = 0.25
    continuous_peaks: tuple[str, ...] = ("vsotf",)
    peak_method: str = "local"
    cutoff_threshold: float = 0.05
    dof_fraction: float = 0.8
    chunk_size: int = 8
    options: ModelOptions = field(default_factory=ModelOptions)
    base_dir: str = field(default=".", compare=False)

    def __post_init__(self):
        # Direct construction (the Python API) gets the same checks as a TOML file.
        for name in ("pupil_diameters_mm", "depth_offsets_D", "wavelengths_nm", "layouts",
                     "continuous_peaks"):
            value = getattr(self, name)
            if isinstance(value, (list, np.ndarray)):
                object.__setattr__(self, name, tuple(np.asarray(value).tolist()))
            elif isinstance(value, str):
                object.__setattr__(self, name, (value,))
        problems = _range_problems(_flat(self), Path(self.base_dir))
        if problems:
            raise SweepConfigError(problems, "SweepConfig")

    # --------------------------------------------------------------- derived (host numpy)
    @property
    def fit_pupil_mm(self) -> float:
        """The Thibos fit sampled (mm)."""
        if self.measured_pupil_mm is not None:
            return float(self.measured_pupil_mm)
        largest = max(self.pupil_diameters_mm)
        return float(min(p for p in THIBOS_PUPILS_MM if p >= largest - 1e-9))

    @property
    def depths_D(self) -> np.ndarray:
        return np.round(self.cdp_D + np.asarray(self.depth_offsets_D, float), 9)

    @property
    def accommodation_D(self) -> np.ndarray:
        return _grid(0.0, self.accommodation_max_D, self.accommodation_step_D)

    @property
    def wavelength_step_planned(self) -> bool:
        """True when ``wavelengths_nm`` gives no step (the planner chooses it)."""
        return len(self.wavelengths_nm) == 2

    @property
    def wavelength_grid_nm(self) -> np.ndarray:
        """The fixed grid (nm); a planned step comes from
        :func:`lfjax.sweep.compute.sweep_spectrum`."""
        if self.wavelength_step_planned:
            raise ValueError("wavelengths_nm gives no step: the sweep plans it "
                             "(lfjax.sweep.compute.sweep_spectrum)")
        return _grid(*self.wavelengths_nm)

    def display_optics(self):
        """The display's :class:`~lfjax.display.lenslets.DisplayOptics`, or None (ideal display)."""
        if self.lenslet_distance_mm is not None:
            return display_optics_at(self.lenslet_distance_mm, self.cdp_D, self.pixel_width_arcmin)
        if self.pixel_width_arcmin > 0:
            return DisplayOptics(pixel_width_arcmin=self.pixel_width_arcmin)
        return None

    @property
    def n_total_eyes(self) -> int:
        """Virtual eyes plus the average eye when it is included."""
        return int(self.n_eyes) + int(bool(self.average_eye))

    @property
    def n_chunks(self) -> int:
        return -(-self.n_total_eyes // int(self.chunk_size))

    def layout_path(self, entry: str) -> Path | None:
        """The JSON file a layout entry names (None for a named paper layout)."""
        if entry in PAPER_LAYOUTS:
            return None
        path = Path(entry)
        return path if path.is_absolute() else Path(self.base_dir) / path

    def as_dict(self) -> dict:
        """Canonical, JSON-safe description (what a store records and resumes against)."""
        out = {"format": CONFIG_FORMAT}
        for f in dataclasses.fields(self):
            if f.name == "base_dir":
                continue
            value = getattr(self, f.name)
            if f.name == "options":
                value = value.as_dict()
            elif isinstance(value, tuple):
                value = list(value)
            out[f.name] = value
        out["fit_pupil_mm"] = self.fit_pupil_mm
        out["layout_files"] = {
            entry: json.loads(path.read_text()) for entry in self.layouts
            if (path := self.layout_path(entry)) is not None
        }
        return out

    def to_json(self) -> str:
        return json.dumps(self.as_dict(), sort_keys=True)

    def replace(self, **changes) -> SweepConfig:
        """A copy with some fields changed (validated again)."""
        return config_from_dict(_flat_to_sections({**_flat(self), **changes}),
                                base_dir=self.base_dir)


# --------------------------------------------------------------------------- the TOML schema

# section -> {key: (field name, kind)}; kinds are checked by _convert
_SCHEMA: dict[str, dict[str, tuple[str, str]]] = {
    "population": {
        "n_eyes": ("n_eyes", "int"),
        "seed": ("seed", "int"),
        "measured_pupil_mm": ("measured_pupil_mm", "float"),
        "pupil_diameters_mm": ("pupil_diameters_mm", "floats"),
        "average_eye": ("average_eye", "bool"),
    },
    "display": {
        "layouts": ("layouts", "strings"),
        "cdp_D": ("cdp_D", "float"),
        "depth_offsets_D": ("depth_offsets_D", "floats"),
        "lenslet_distance_mm": ("lenslet_distance_mm", "float"),
        "pixel_width_arcmin": ("pixel_width_arcmin", "float"),
    },
    "accommodation": {
        "step_D": ("accommodation_step_D", "float"),
        "max_D": ("accommodation_max_D", "float"),
        "window_D": ("window_D", "float"),
    },
    "spectrum": {
        "wavelengths_nm": ("wavelengths_nm", "floats"),
        "display": ("display_spectrum", "string"),
    },
    "sampling": {
        "freq_step_cpd": ("freq_step_cpd", "float_or_planned"),
        "vsotf_tolerance": ("vsotf_tolerance", "float"),
        "peak_tolerance_D": ("peak_tolerance_D", "float"),
        "cutoff_tolerance_cpd": ("cutoff_tolerance_cpd", "float"),
    },
    "metrics": {
        "continuous_peaks": ("continuous_peaks", "strings"),
        "peak_method": ("peak_method", "string"),
        "cutoff_threshold": ("cutoff_threshold", "float"),
        "dof_fraction": ("dof_fraction", "float"),
    },
    "run": {
        "chunk_size": ("chunk_size", "int"),
    },
}
_MODEL_KEYS = {f.name for f in dataclasses.fields(ModelOptions)}


def _flat(config: SweepConfig) -> dict:
    return {f.name: getattr(config, f.name) for f in dataclasses.fields(config)
            if f.name != "base_dir"}


def _flat_to_sections(flat: dict) -> dict:
    out: dict = {}
    for section, keys in _SCHEMA.items():
        for key, (name, _) in keys.items():
            if name in flat and flat[name] is not None:
                value = flat[name]
                out.setdefault(section, {})[key] = list(value) if isinstance(value, tuple) else value
    options = flat.get("options")
    if options is not None:
        out["model"] = options.as_dict() if isinstance(options, ModelOptions) else dict(options)
    return out


def _suggest(key: str, known) -> str:
    close = difflib.get_close_matches(key, list(known), n=1, cutoff=0.5)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _convert(where: str, value, kind: str, problems: list[str]):
    """Type-check one value; returns the converted value or None (problem recorded)."""
    if kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            problems.append(f"{where} must be a whole number, got {value!r}")
            return None
        return int(value)
    if kind == "float":
        if not _is_number(value) or not math.isfinite(float(value)):
            problems.append(f"{where} must be a finite number, got {value!r}")
            return None
        return float(value)
    if kind == "float_or_planned":
        if value == "planned":
            return None
        if not _is_number(value) or not math.isfinite(float(value)):
            problems.append(f"{where} must be a number (cpd) or \"planned\", got {value!r}")
            return None
        return float(value)
    if kind == "bool":
        if not isinstance(value, bool):
            problems.append(f"{where} must be true or false, got {value!r}")
            return None
        return value
    if kind == "string":
        if not isinstance(value, str):
            problems.append(f"{where} must be a string, got {value!r}")
            return None
        return value
    if kind in ("floats", "strings"):
        if not isinstance(value, (list, tuple)):
            problems.append(f"{where} must be a list, got {value!r}")
            return None
        check = _is_number if kind == "floats" else (lambda x: isinstance(x, str))
        bad = [x for x in value if not check(x) or (kind == "floats" and not math.isfinite(x))]
        if bad:
            what = "finite numbers" if kind == "floats" else "strings"
            problems.append(f"{where} must be a list of {what}, got {bad!r} in it")
            return None
        return tuple(float(x) for x in value) if kind == "floats" else tuple(value)
    raise AssertionError(kind)


def config_from_dict(data: dict, base_dir: str | Path = ".", source: str = "sweep config"
                     ) -> SweepConfig:
    """A validated :class:`SweepConfig` from the TOML structure (sections of keys).

    Raises :class:`SweepConfigError` listing every problem.
    """
    problems: list[str] = []
    values: dict = {}
    if not isinstance(data, dict):
        raise SweepConfigError([f"expected a table of sections, got {type(data).__name__}"], source)
    known_sections = list(_SCHEMA) + ["model"]
    for section, body in data.items():
        if section not in known_sections:
            problems.append(f"unknown section [{section}]{_suggest(section, known_sections)}; "
                            f"known: {', '.join(known_sections)}")
            continue
        if not isinstance(body, dict):
            problems.append(f"[{section}] must be a table of keys, got {body!r}")
            continue
        if section == "model":
            for key, value in body.items():
                if key not in _MODEL_KEYS:
                    problems.append(f"model.{key}: unknown model option{_suggest(key, _MODEL_KEYS)}"
                                    f"; known: {', '.join(sorted(_MODEL_KEYS))}")
            continue
        keys = _SCHEMA[section]
        for key, value in body.items():
            if key not in keys:
                all_keys = {k for s in _SCHEMA.values() for k in s}
                hint = _suggest(key, keys) or _suggest(key, all_keys)
                problems.append(f"{section}.{key}: unknown key{hint}; known in [{section}]: "
                                f"{', '.join(keys)}")
                continue
            name, kind = keys[key]
            converted = _convert(f"{section}.{key}", value, kind, problems)
            if converted is not None or kind == "float_or_planned":
                values[name] = converted

    options = ModelOptions()
    model = data.get("model") if isinstance(data.get("model"), dict) else {}
    model = {k: v for k, v in model.items() if k in _MODEL_KEYS}
    if model:
        try:
            options = ModelOptions(**model)
        except (TypeError, ValueError) as err:
            problems.append(f"model: {err}")
    values["options"] = options
    defaults = SweepConfig.__dataclass_fields__
    merged = {name: values.get(name, f.default if f.default is not dataclasses.MISSING
                               else f.default_factory())
              for name, f in defaults.items() if name != "base_dir"}
    merged["options"] = options
    problems += _range_problems(merged, Path(base_dir))
    if problems:
        raise SweepConfigError(problems, source)
    return SweepConfig(**merged, base_dir=str(base_dir))


def _range_problems(v: dict, base_dir: Path) -> list[str]:
    """Every impossible value or combination (the values' types are already right)."""
    p: list[str] = []
    if v["n_eyes"] < 1:
        p.append(f"population.n_eyes must be >= 1, got {v['n_eyes']}")
    if not (0 <= v["seed"] < 2**32):
        p.append(f"population.seed must be in [0, 2**32), got {v['seed']}")
    pupils = v["pupil_diameters_mm"]
    if not pupils:
        p.append("population.pupil_diameters_mm must list at least one pupil (mm)")
    elif any(d < MIN_PUPIL_MM - 1e-9 for d in pupils):
        p.append(f"population.pupil_diameters_mm must be >= {MIN_PUPIL_MM:g} mm (the human "
                 f"pupil's range; the eye model and its Thibos statistics are for "
                 f"{MIN_PUPIL_MM:g}-{max(THIBOS_PUPILS_MM):g} mm), got {list(pupils)}")
    elif len(set(pupils)) != len(pupils):
        p.append(f"population.pupil_diameters_mm has repeated values: {list(pupils)}")
    measured = v["measured_pupil_mm"]
    if measured is not None and measured not in THIBOS_PUPILS_MM:
        p.append(f"population.measured_pupil_mm must be one of {list(THIBOS_PUPILS_MM)} mm "
                 f"(the Thibos et al. 2002 fits), got {measured}")
    elif pupils and all(d > 0 for d in pupils):
        limit = measured if measured is not None else max(THIBOS_PUPILS_MM)
        too_big = [d for d in pupils if d > limit + 1e-9]
        if too_big:
            p.append(f"population.pupil_diameters_mm {too_big} exceed the measured pupil "
                     f"({limit:g} mm): allowed range (0, {limit:g}] mm")
    layouts = v["layouts"]
    if not layouts:
        p.append(f"display.layouts must list at least one layout ({', '.join(PAPER_LAYOUTS)} or a "
                 "layout JSON file)")
    if len(set(layouts)) != len(layouts):
        p.append(f"display.layouts has repeated entries: {list(layouts)}")
    for entry in layouts:
        if entry in PAPER_LAYOUTS:
            continue
        if not entry.endswith(".json"):
            p.append(f"display.layouts: {entry!r} is neither a paper layout "
                     f"({', '.join(PAPER_LAYOUTS)}) nor a .json layout file")
            continue
        path = Path(entry) if Path(entry).is_absolute() else base_dir / entry
        if not path.is_file():
            p.append(f"display.layouts: layout file {str(path)!r} does not exist")
            continue
        try:
            load_layout_json(path)
        except (ValueError, OSError, json.JSONDecodeError) as err:
            p.append(f"display.layouts: {path}: {err}")
    if v["cdp_D"] < 0:
        p.append(f"display.cdp_D must be >= 0 D (0 D is optical infinity), got {v['cdp_D']}")
    offsets = v["depth_offsets_D"]
    if not offsets:
        p.append("display.depth_offsets_D must list at least one depth (D)")
    else:
        if any(v["cdp_D"] + d < -1e-9 for d in offsets):
            p.append(f"display.depth_offsets_D: every rendered depth cdp_D + offset must be >= 0 D; "
                     f"cdp_D = {v['cdp_D']} with offsets {list(offsets)}")
        if len(set(np.round(offsets, 9))) != len(offsets):
            p.append(f"display.depth_offsets_D has repeated values: {list(offsets)}")
        if "natural" in layouts and 0.0 not in [round(d, 9) for d in offsets]:
            p.append("display.depth_offsets_D must include 0 when layouts include 'natural' "
                     "(natural view is evaluated at the CDP)")
    if v["accommodation_step_D"] <= 0:
        p.append(f"accommodation.step_D must be > 0 D, got {v['accommodation_step_D']}")
    elif (v["accommodation_max_D"] > 0
          and v["accommodation_max_D"] / v["accommodation_step_D"] > MAX_ACCOMMODATION_STATES):
        p.append(f"accommodation.step_D = {v['accommodation_step_D']:g} D makes "
                 f"{v['accommodation_max_D'] / v['accommodation_step_D']:.3g} states on "
                 f"0 ... max_D = {v['accommodation_max_D']:g} D: at most "
                 f"{MAX_ACCOMMODATION_STATES} (step >= "
                 f"{v['accommodation_max_D'] / MAX_ACCOMMODATION_STATES:.2g} D); continuous peaks "
                 f"(metrics.continuous_peaks) refine off the grid")
    if v["accommodation_max_D"] <= 0:
        p.append(f"accommodation.max_D must be > 0 D, got {v['accommodation_max_D']}")
    if v["window_D"] <= 0:
        p.append(f"accommodation.window_D must be > 0 D, got {v['window_D']}")
    elif v["accommodation_step_D"] > 0 and v["window_D"] < v["accommodation_step_D"]:
        p.append(f"accommodation.window_D ({v['window_D']} D) must be >= step_D "
                 f"({v['accommodation_step_D']} D): a peak needs >= 2 states per depth")
    if (offsets and v["accommodation_max_D"] > 0 and v["cdp_D"] >= 0
            and max(v["cdp_D"] + d for d in offsets) - v["window_D"] > v["accommodation_max_D"]):
        p.append(f"accommodation.max_D ({v['accommodation_max_D']} D) leaves no state within "
                 f"window_D of the nearest rendered depth")
    wl = v["wavelengths_nm"]
    if not (0 < v["peak_tolerance_D"] <= 0.5):
        p.append(f"sampling.peak_tolerance_D must be in (0, 0.5] D, got {v['peak_tolerance_D']}")
    if not (0 < v["cutoff_tolerance_cpd"] <= 10):
        p.append(f"sampling.cutoff_tolerance_cpd must be in (0, 10] cpd, got "
                 f"{v['cutoff_tolerance_cpd']}")
    if len(wl) == 2 and v["display_spectrum"] is not None:
        p.append("spectrum.wavelengths_nm needs a step with spectrum.display (the step is the "
                 "width of the display spectrum's cells): [start, stop, step] in nm")
    if len(wl) not in (2, 3):
        p.append(f"spectrum.wavelengths_nm must be [start, stop] (step planned) or "
                 f"[start, stop, step] in nm, got {list(wl)}")
    else:
        start, stop, step = wl if len(wl) == 3 else (*wl, 5.0)
        if not (step > 0 and stop >= start):
            p.append(f"spectrum.wavelengths_nm: need step > 0 and stop >= start, got {list(wl)}")
        elif step < MIN_WAVELENGTH_STEP_NM - 1e-12:
            p.append(f"spectrum.wavelengths_nm step must be >= {MIN_WAVELENGTH_STEP_NM:g} nm "
                     f"(the tabulation interval of the luminous-efficiency data; a finer step "
                     f"only interpolates), got {step:g} nm ({(stop - start) / step + 1:.3g} "
                     f"wavelengths)")
        sce_on = v["options"].sce != "off"
        lo, hi = (400.0, 700.0) if sce_on else (390.0, 830.0)
        if start < lo - 1e-9 or stop > hi + 1e-9:
            p.append(f"spectrum.wavelengths_nm must lie in [{lo:g}, {hi:g}] nm "
                     f"({'Stiles-Crawford data' if sce_on else 'luminous efficiency data'}), got "
                     f"{list(wl)}")
    distance = v.get("lenslet_distance_mm")
    if distance is not None:
        limit = 1000.0 / v["cdp_D"] if v["cdp_D"] > 0 else math.inf
        if not (0 < distance < limit):
            p.append(f"display.lenslet_distance_mm must be in (0, {limit:.4g}) mm (the CDP is a "
                     f"virtual image behind the display), got {distance}")
    if v.get("pixel_width_arcmin", 0.0) < 0:
        p.append(f"display.pixel_width_arcmin must be >= 0 arcmin, got {v['pixel_width_arcmin']}")
    name = v.get("display_spectrum")
    if name is not None:
        if name not in DISPLAY_NAMES:
            p.append(f"spectrum.display must be one of {', '.join(DISPLAY_NAMES)}, got {name!r}")
    if v["freq_step_cpd"] is not None and v["freq_step_cpd"] <= 0:
        p.append(f"sampling.freq_step_cpd must be > 0 cpd (or \"planned\"), got {v['freq_step_cpd']}")
    tol = v["vsotf_tolerance"]
    if tol is not None:
        if not (0 < tol < 0.1):
            p.append(f"sampling.vsotf_tolerance must be in (0, 0.1), got {tol}")
        if v["freq_step_cpd"] is not None:
            p.append("sampling.vsotf_tolerance plans the frequency step: give it or "
                     "freq_step_cpd, not both")
    bad = [m for m in v["continuous_peaks"] if m not in METRICS]
    if bad:
        p.append(f"metrics.continuous_peaks must name metrics in {list(METRICS)}, got {bad}")
    if v["peak_method"] not in PEAK_METHODS:
        p.append(f"metrics.peak_method must be one of {list(PEAK_METHODS)}, got {v['peak_method']!r}")
    if not (0 < v["cutoff_threshold"] < 1):
        p.append(f"metrics.cutoff_threshold must be in (0, 1), got {v['cutoff_threshold']}")
    if not (0 < v["dof_fraction"] < 1):
        p.append(f"metrics.dof_fraction must be in (0, 1), got {v['dof_fraction']}")
    if v["chunk_size"] < 1:
        p.append(f"run.chunk_size must be >= 1 eye, got {v['chunk_size']}")
    return p


def load_config(path) -> SweepConfig:
    """Read and validate a sweep TOML file (relative layout paths are relative to it)."""
    path = Path(path)
    if path.is_dir():
        raise SweepConfigError([f"{str(path)!r} is a folder, not a TOML config file (lfjax "
                                f"sweep --template CONFIG.toml writes one)"], str(path))
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise SweepConfigError([f"config file {str(path)!r} does not exist"], str(path)) from None
    except (OSError, UnicodeDecodeError) as err:
        raise SweepConfigError([f"cannot read the config file: {err}"], str(path)) from None
    except tomllib.TOMLDecodeError as err:
        raise SweepConfigError([f"not valid TOML: {err}"], str(path)) from None
    if not data:
        # an empty file would otherwise start the default sweep (1,000 eyes, hours)
        raise SweepConfigError(["the config file sets nothing: write at least one section "
                                "(lfjax sweep --template CONFIG.toml writes every key with "
                                "its default)"], str(path))
    return config_from_dict(data, base_dir=path.parent, source=str(path))


def config_to_toml(config: SweepConfig) -> str:
    """TOML text that :func:`load_config` reads back into ``config``."""
    sections = _flat_to_sections(_flat(config))
    lines = []
    for section, body in sections.items():
        lines.append(f"[{section}]")
        for key, value in body.items():
            lines.append(f"{key} = {_toml_value(value)}")
        lines.append("")
    return "\n".join(lines)


_KEY_HELP = {
    "n_eyes": "virtual eyes, Thibos et al. (2002), sample_eyes(seed, n)",
    "seed": "seed of the draw, 0 <= seed < 2**32",
    "measured_pupil_mm": "Thibos fit (3, 4.5, 6 or 7.5 mm); default: the smallest holding "
                         "the largest pupil",
    "pupil_diameters_mm": f"calculation pupils, mm ({MIN_PUPIL_MM:g} mm up to the measured pupil)",
    "average_eye": "append the Thibos average eye (claims 4 and 5 need it)",
    "layouts": "paper layouts (natural, 2x2, 3x3, 4x4) or layout JSON files",
    "cdp_D": "central depth plane, D",
    "depth_offsets_D": "rendered depths relative to the CDP, D",
    "lenslet_distance_mm": "lenslet diffraction of an array this far from the eye, mm",
    "pixel_width_arcmin": "emitters' angular width, arcmin (0: points)",
    "step_D": "absolute accommodation grid 0 ... max_D, step in D",
    "max_D": "last state of the grid, D",
    "window_D": "each depth is evaluated within +-window_D of it, D",
    "wavelengths_nm": f"start, stop[, step] in nm (step >= {MIN_WAVELENGTH_STEP_NM:g} nm; "
                      f"without it the step is planned for the targets below)",
    "display": "a display's white (crt, lcd, oled, laser) instead of V(lambda) white",
    "freq_step_cpd": "OTF frequency step, cpd, or \"planned\" (once, on the whole population)",
    "vsotf_tolerance": "plan for this VSOTF accuracy (the planner's proxy)",
    "peak_tolerance_D": "a planned wavelength step moves no peak by more, D",
    "cutoff_tolerance_cpd": "a planned wavelength step moves no cut-off by more, cpd",
    "continuous_peaks": "metrics refined off the grid (lfjax.vision.peaks)",
    "peak_method": f"refinement: {', '.join(PEAK_METHODS)}",
    "cutoff_threshold": "MTF value defining the cut-off frequency",
    "dof_fraction": "depth of field fraction (claim 6)",
    "chunk_size": "eyes per compiled call; memory grows with it",
}
_EXAMPLES = {"measured_pupil_mm": 6.0, "lenslet_distance_mm": 300.0, "display": "oled",
             "vsotf_tolerance": 1e-3}


def config_template() -> str:
    """A commented TOML config with every key at its default (keys whose default is "not
    set" are commented out with an example value); :func:`load_config` reads it as
    ``SweepConfig()``. ``lfjax sweep --template CONFIG.toml`` writes it."""
    default = SweepConfig()
    lines = [f"# lfjax sweep configuration ({CONFIG_FORMAT}): every key with its default.",
             "# Units are in the key names: _D dioptres, _mm millimetres, _nm nanometres,",
             "# _cpd cycles per degree. Run: lfjax sweep THIS.toml --dry-run", ""]
    for section, keys in _SCHEMA.items():
        lines.append(f"[{section}]")
        for key, (name, kind) in keys.items():
            value = getattr(default, name)
            if kind == "float_or_planned" and value is None:
                text, prefix = '"planned"', ""
            elif value is None:
                text, prefix = _toml_value(_EXAMPLES[key]), "# "
            else:
                text, prefix = _toml_value(value), ""
            lines.append(f"{prefix}{key} = {text}  # {_KEY_HELP[key]}")
        lines.append("")
    lines.append("[model]  # lfjax.ModelOptions fields")
    for key, value in ModelOptions().as_dict().items():
        if value is not None:
            lines.append(f"{key} = {_toml_value(value)}")
        else:
            lines.append(f"# {key} = (not set)")
    return "\n".join(lines) + "\n"


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in value) + "]"
    return repr(value)


def config_differences(stored: dict, current: dict, prefix: str = "") -> list[str]:
    """Human-readable differences between two :meth:`SweepConfig.as_dict` records."""
    out = []
    for key in sorted(set(stored) | set(current)):
        a, b = stored.get(key, "<absent>"), current.get(key, "<absent>")
        if isinstance(a, dict) and isinstance(b, dict):
            out += config_differences(a, b, f"{prefix}{key}.")
        elif a != b:
            out.append(f"{prefix}{key}: store has {a!r}, config has {b!r}")
    return out


__all__ = [
    "CONFIG_FORMAT",
    "SweepConfig",
    "SweepConfigError",
    "config_from_dict",
    "config_differences",
    "config_template",
    "config_to_toml",
    "load_config",
]
