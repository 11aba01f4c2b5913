"""A population sweep's configuration: read from TOML, validated whole before any compute.

:class:`SweepConfig` names the population (eyes, seed, pupils), the display (layouts, CDP,
rendered depths), the accommodation grid, the spectrum, the sampling, the metrics, the model
options and the chunk size. :func:`config_from_dict` takes the TOML structure as a dict
(:func:`lfjax.sweep.config_files.load_config` reads a TOML file). Every problem found
(unknown keys, values of the wrong type or unit, impossible ranges) is collected and raised
once as :class:`~lfjax.sweep.config_keys.SweepConfigError`, one line per problem, so a user
fixes the file in one pass.

Each key is declared once, on its :class:`SweepConfig` field: the field gives its name, type
and default, and its metadata (a :class:`~lfjax.sweep.config_keys.Key`) its section, unit,
help line, allowed values and an example (the vocabulary: :mod:`lfjax.sweep.config_keys`).
:data:`KEYS` collects them; the TOML schema (:data:`SCHEMA`), the type and range checks,
:func:`~lfjax.sweep.config_files.config_template` and the key list in ``SweepConfig``'s
docstring are derived from it. Checks that relate several keys (a pupil against the measured
pupil, a depth against the CDP, …) are written once, below the keys.

Units are part of the key names (:data:`~lfjax.sweep.config_keys.UNIT_SUFFIXES`: ``_D``
dioptres, ``_mm`` millimetres, ``_nm`` nanometres, ``_cpd`` cycles per degree, ``_arcmin``
arcminutes); a key with another unit suffix is reported as unknown with the key it probably
meant.
"""

from __future__ import annotations

import dataclasses
import difflib
import json
import math
import textwrap
import types
import typing
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lfjax.base.apertures import STRIP
from lfjax.base.errors import ParameterError
from lfjax.base.grids import DepthGrid, inclusive_grid
from lfjax.base.units import check_dioptres
from lfjax.display.aberrations import LensletAberration
from lfjax.display.lenslets import DisplayOptics, display_optics_at
from lfjax.display.lenticular import MAX_Y_DEFOCUS_D, ViewOptics
from lfjax.display.spectra import DISPLAY_NAMES
from lfjax.model.eyes import THIBOS_PUPILS_MM
from lfjax.model.layout_files import load_layout_json
from lfjax.model.layouts import Layout, PAPER_LAYOUTS, check_views_in_pupil
from lfjax.model.strips import neighbour_matrix
from lfjax.model.options import ModelOptions
from lfjax.vision.peak_options import METRICS, PEAK_METHODS
from lfjax.sweep.config_keys import (
    check_layout_entries,
    check_wavelength_grid,
    CONFIG_FORMAT,
    Distinct,
    Key,
    key_metadata,
    MAX_ACCOMMODATION_STATES,
    MAX_STRIP_VIEWS,
    MAX_STRIP_WIDTH_RATIO,
    MIN_PUPIL_MM,
    MIN_WAVELENGTH_STEP_NM,
    NonEmpty,
    OneOf,
    Range,
    strip_views,
    SweepConfigError,
    toml_value,
    UNIT_SUFFIXES,
)



# --------------------------------------------------------------------------- the keys

@dataclass(frozen=True)
class SweepConfig(DepthGrid):
    """Everything a sweep computes (defaults: the paper's scene on 1,000 eyes).

    Every field but ``options`` and ``base_dir`` is one key of the TOML file, declared once
    on the field (:class:`~lfjax.sweep.config_keys.Key`); the list of keys below, with their
    types, defaults, units and allowed values, is derived from those declarations.
    ``options`` is the ``[model]`` table (any :class:`lfjax.ModelOptions` field);
    ``base_dir`` is the folder relative layout paths start from (the config file's).

    Eyes come from ``sample_eyes(seed, n_eyes)`` on the Thibos fit of ``fit_pupil_mm`` and are
    evaluated inside every pupil of ``pupil_diameters_mm``. Each depth ``cdp_D + offset`` is
    evaluated on the states of the absolute grid 0 … ``max_D`` within ±``window_D`` of it.
    Without a wavelength step each (pupil, layout) gets its own planned spectrum
    (:func:`lfjax.sweep.compute.sweep_spectra`): the coarsest uniform step whose proxy peaks
    stay within ``peak_tolerance_D`` and cut-offs within ``cutoff_tolerance_cpd``, or the
    Gauss rule in V(λ) with the fewest nodes that does so when they are fewer (11, 9, 6 and 5
    nodes for the paper's natural view, 2×2, 3×3 and 4×4); a step given is one uniform grid
    for every layout. A planned frequency step comes from
    :func:`lfjax.planner.plan.plan_sampling` on the whole population.
    """

    n_eyes: int = field(default=1000, metadata=key_metadata(
        "population", "virtual eyes drawn from Thibos et al. (2002), sample_eyes(seed, n_eyes)",
        Range(lo=1)))
    seed: int = field(default=0, metadata=key_metadata(
        "population", "seed of the draw", Range(0, 2**32, hi_open=True, text="[0, 2**32)")))
    measured_pupil_mm: float | None = field(default=None, metadata=key_metadata(
        "population", "which Thibos fit to sample; the eyes are evaluated inside every pupil "
        "of pupil_diameters_mm (each <= it); not set: the smallest fit holding the largest pupil",
        OneOf(THIBOS_PUPILS_MM, note="the Thibos et al. 2002 fits"), example=6.0))
    pupil_diameters_mm: tuple[float, ...] = field(default=(3.0,), metadata=key_metadata(
        "population", "calculation pupils, up to the measured pupil",
        NonEmpty("pupil (mm)"),
        Range(lo=MIN_PUPIL_MM, tol=1e-9,
              note=f"the human pupil's range; the eye model and its Thibos statistics are for "
                   f"{MIN_PUPIL_MM:g}-{max(THIBOS_PUPILS_MM):g} mm"),
        Distinct()))
    average_eye: bool = field(default=True, metadata=key_metadata(
        "population", "append the Thibos average eye (of the measured pupil), flagged "
        "is_average (claims 4 and 5 compare against it)"))
    layouts: tuple[str, ...] = field(default=PAPER_LAYOUTS, metadata=key_metadata(
        "display", f"paper layouts ({', '.join(PAPER_LAYOUTS)}, sized to each pupil), "
        f"horizontal-parallax-only strips 1xN (N = 1 ... {MAX_STRIP_VIEWS} vertical strips "
        f"across each pupil, pitch pupil/N: lfjax.model.strips.strip_layout) or layout JSON "
        f"files of lfjax optimise (fixed in mm; relative to the config file)",
        NonEmpty(f"layout ({', '.join(PAPER_LAYOUTS)} or a layout JSON file)"), Distinct(),
        check_layout_entries))
    cdp_D: float = field(default=2.0, metadata=key_metadata(
        "display", "central depth plane", Range(lo=0, note="0 D is optical infinity")))
    depth_offsets_D: tuple[float, ...] = field(
        default=tuple(inclusive_grid(-2.0, 2.0, 0.5).tolist()), metadata=key_metadata(
            "display", "rendered depths relative to the CDP (the natural view: the CDP only)",
            NonEmpty("depth (D)"), Distinct()))
    lenslet_distance_mm: float | None = field(default=None, metadata=key_metadata(
        "display", "a lenslet-array display this far from the eye: each view is its "
        "lenslet's Fresnel pattern (lfjax.display.lenslets.display_optics_at); not set: the "
        "paper's ideal display", example=300.0))
    pixel_width_arcmin: float = field(default=0.0, metadata=key_metadata(
        "display", "angular width of the emitters (0: points)", Range(lo=0)))
    lenslet_spherical_um: float = field(default=0.0, metadata=key_metadata(
        "display", "lenslets' spherical aberration W040 at each view's rim "
        "(lfjax.display.aberrations; 0: aberration-free)", Range(lo=-100, hi=100)))
    lenslet_coma_um: float = field(default=0.0, metadata=key_metadata(
        "display", "lenslets' coma W131 at each view's rim, tilt removed, field along x",
        Range(lo=-100, hi=100)))
    lenslet_astigmatism_um: float = field(default=0.0, metadata=key_metadata(
        "display", "lenslets' astigmatism W222 at each view's rim, field along x",
        Range(lo=-100, hi=100)))
    lenslet_field_curvature_um: float = field(default=0.0, metadata=key_metadata(
        "display", "lenslets' field curvature W220 at each view's rim", Range(lo=-100, hi=100)))
    strip_width_ratio: float = field(default=1.0, metadata=key_metadata(
        "display", "width / pitch of the 1xN layouts' strips, unitless (below 1 gaps "
        "between the strips, above 1 overlap; 1: tangent strips filling the pupil)",
        Range(0, MAX_STRIP_WIDTH_RATIO, lo_open=True,
              note="at 2 a strip reaches its neighbours' centres")))
    strip_y_defocus_D: float = field(default=0.0, metadata=key_metadata(
        "display", "the 1xN strips' extra defocus along y against x (an astigmatic "
        "lenticular beam: a panel's CDP minus the vergence of its pixel plane, "
        "lfjax.display.lenticular.LenticularPanel.y_defocus_D; about -0.83 D for "
        "lenticular_phone(), -28.5 D for lenticular_near_eye()); 0: the idealised 1-D light "
        "field", Range(-MAX_Y_DEFOCUS_D, MAX_Y_DEFOCUS_D)))
    leakage_weight: float = field(default=0.0, metadata=key_metadata(
        "display", "weight of each neighbouring view's content in a view, unitless "
        "(cross-talk, lfjax.display.lenticular.ViewOptics; the neighbours are the nearest "
        "views: adjacent strips, the edge neighbours of a grid); 0: none",
        Range(0, 1)))
    accommodation_step_D: float = field(default=0.2, metadata=key_metadata(
        "accommodation", "step of the absolute accommodation grid 0 ... max_D",
        Range(lo=0, lo_open=True), name="step_D"))
    accommodation_max_D: float = field(default=5.0, metadata=key_metadata(
        "accommodation", "last state of the grid", Range(lo=0, lo_open=True), name="max_D"))
    window_D: float = field(default=2.0, metadata=key_metadata(
        "accommodation", "each depth is evaluated within +-window_D of it",
        Range(lo=0, lo_open=True)))
    wavelengths_nm: tuple[float, ...] = field(default=(400.0, 700.0), metadata=key_metadata(
        "spectrum", f"start, stop[, step] (step >= {MIN_WAVELENGTH_STEP_NM:g} nm; without it "
        f"the step is planned for peak_tolerance_D and cutoff_tolerance_cpd)",
        check_wavelength_grid))
    display_spectrum: str | None = field(default=None, metadata=key_metadata(
        "spectrum", "a built-in display's white weighted by V(lambda), on the wavelengths "
        "that carry it, instead of V(lambda) white (needs a wavelength step: the cells' "
        "width); not set: V(lambda) white", OneOf(DISPLAY_NAMES), name="display",
        example="oled"))
    freq_step_cpd: float | None = field(default=None, metadata=key_metadata(
        "sampling", "frequency step of the OTF grid, or \"planned\": per (pupil, layout) by "
        "lfjax.planner.plan.plan_sampling, once, on the whole population",
        Range(lo=0, lo_open=True), none_word="planned"))
    vsotf_tolerance: float | None = field(default=None, metadata=key_metadata(
        "sampling", "with a planned frequency step: the planner's VSOTF accuracy target (its "
        "proxy runs, seconds per layout); not set: its field guard alone (milliseconds)",
        Range(0, 0.1, lo_open=True, hi_open=True), example=1e-3))
    peak_tolerance_D: float = field(default=0.01, metadata=key_metadata(
        "sampling", "a planned wavelength step moves no peak by more, and the adaptive peak "
        "method refines every peak whose grid estimate may be further off",
        Range(0, 0.5, lo_open=True)))
    cutoff_tolerance_cpd: float = field(default=0.25, metadata=key_metadata(
        "sampling", "a planned wavelength step moves no cut-off by more",
        Range(0, 10, lo_open=True)))
    continuous_peaks: tuple[str, ...] = field(default=("vsotf",), metadata=key_metadata(
        "metrics", "metrics whose peak is refined off the grid (lfjax.vision.peaks)",
        OneOf(METRICS)))
    peak_method: str = field(default="adaptive", metadata=key_metadata(
        "metrics", "how a peak is refined (lfjax.vision.peak_options.PEAK_METHODS)",
        OneOf(PEAK_METHODS)))
    cutoff_threshold: float = field(default=0.05, metadata=key_metadata(
        "metrics", "MTF value defining the cut-off frequency",
        Range(0, 1, lo_open=True, hi_open=True)))
    dof_fraction: float = field(default=0.8, metadata=key_metadata(
        "metrics", "depth of field fraction (claim 6; the report's population claims)",
        Range(0, 1, lo_open=True, hi_open=True)))
    chunk_size: int = field(default=8, metadata=key_metadata(
        "run", "eyes per compiled call (memory grows linearly with it); a multiple of the "
        "number of local devices when sharded", Range(lo=1)))
    options: ModelOptions = field(default_factory=ModelOptions)
    base_dir: str = field(default=".", compare=False)

    def __post_init__(self):
        # Direct construction (the Python API) gets the same checks as a TOML file.
        for key in KEYS:
            if key.kind not in ("floats", "strings"):
                continue
            value = getattr(self, key.field)
            if isinstance(value, (list, np.ndarray)):
                object.__setattr__(self, key.field, tuple(np.asarray(value).tolist()))
            elif isinstance(value, str):
                object.__setattr__(self, key.field, (value,))
        problems = _range_problems(config_fields(self), Path(self.base_dir))
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
        return inclusive_grid(*self.wavelengths_nm)

    def display_optics(self, entry: str | None = None, layout: Layout | None = None):
        """The display's :class:`~lfjax.display.lenslets.DisplayOptics` for the layout entry
        ``entry`` (resolved to ``layout``, mm), or None (the ideal display).

        A ``1xN`` strip entry, or any layout of several views with ``leakage_weight`` > 0,
        gets a :class:`~lfjax.display.lenticular.ViewOptics`: strip apertures
        (``aperture="strip"``, x-only Fresnel diffraction with a lenslet distance) and
        ``strip_y_defocus_D`` for strips; the leakage weight with the layout's neighbours
        (:func:`~lfjax.model.strips.neighbour_matrix`). Every other entry, and every entry
        while those keys are at their defaults, gets the display every layout shares, as
        before they existed. Without ``entry`` and ``layout``: that shared display (refused
        with leakage, whose neighbours need the layout)."""
        shared = self._shared_display_optics()
        strips = entry is not None and strip_views(entry) is not None
        leaks = self.leakage_weight > 0
        if leaks and layout is None:
            raise ValueError("display.leakage_weight > 0: the display's neighbours come from "
                             "the layout; call display_optics(entry, layout)")
        leaks = leaks and layout.n_subapertures > 1
        if not (strips or leaks):
            return shared
        base = DisplayOptics() if shared is None else shared
        return ViewOptics(diffraction=base.diffraction,
                          aperture=STRIP.name if strips else base.aperture,
                          fresnel_distance_mm=base.fresnel_distance_mm,
                          pixel_width_arcmin=base.pixel_width_arcmin, aberration=base.aberration,
                          y_defocus_D=self.strip_y_defocus_D if strips else 0.0,
                          leakage_weight=self.leakage_weight if leaks else 0.0,
                          neighbours=neighbour_matrix(layout) if leaks else None)

    def _shared_display_optics(self):
        """The lenslets, pixels and aberration every layout of the sweep shares, or None."""
        if self.lenslet_distance_mm is not None:
            optics = display_optics_at(self.lenslet_distance_mm, self.cdp_D, self.pixel_width_arcmin)
        elif self.pixel_width_arcmin > 0:
            optics = DisplayOptics(pixel_width_arcmin=self.pixel_width_arcmin)
        else:
            optics = None
        aberration = self.lenslet_aberration()
        if aberration is None:
            return optics
        return (DisplayOptics() if optics is None else optics).with_aberration(aberration)

    def lenslet_aberration(self):
        """The lenslets' :class:`~lfjax.display.aberrations.LensletAberration` from the
        ``lenslet_*_um`` keys, or None when they are all 0 (the display without one)."""
        values = (self.lenslet_spherical_um, self.lenslet_coma_um, self.lenslet_astigmatism_um,
                  self.lenslet_field_curvature_um)
        if not any(values):
            return None
        return LensletAberration(*values)

    @property
    def n_total_eyes(self) -> int:
        """Virtual eyes plus the average eye when it is included."""
        return int(self.n_eyes) + int(bool(self.average_eye))

    @property
    def n_chunks(self) -> int:
        return -(-self.n_total_eyes // int(self.chunk_size))

    def layout_path(self, entry: str) -> Path | None:
        """The JSON file a layout entry names (None for a named paper or strip layout)."""
        if entry in PAPER_LAYOUTS or strip_views(entry) is not None:
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
        return config_from_dict(config_sections({**config_fields(self), **changes}),
                                base_dir=self.base_dir)


def _declared_keys() -> tuple[Key, ...]:
    """Every field's :class:`~lfjax.sweep.config_keys.Key`, completed from the field (name,
    type, default, unit)."""
    hints = typing.get_type_hints(SweepConfig)
    keys = []
    for f in dataclasses.fields(SweepConfig):
        if "sweep_key" not in f.metadata:
            continue
        declared: Key = f.metadata["sweep_key"]
        hint = hints[f.name]
        args = typing.get_args(hint)
        optional = isinstance(hint, types.UnionType) and type(None) in args
        if optional:
            (hint,) = [a for a in args if a is not type(None)]
        if typing.get_origin(hint) is tuple:
            kind = {float: "floats", str: "strings"}[typing.get_args(hint)[0]]
        else:
            kind = {int: "int", float: "float", bool: "bool", str: "string"}[hint]
        name = declared.name or f.name
        unit = next((s[1:] for s in UNIT_SUFFIXES if name.endswith(s)), "")
        keys.append(dataclasses.replace(declared, name=name, field=f.name, kind=kind,
                                        optional=optional, default=f.default, unit=unit))
    return tuple(keys)


KEYS: tuple[Key, ...] = _declared_keys()
"""Every key of a sweep's TOML file, in the order of :class:`SweepConfig`'s fields."""

SCHEMA: dict[str, dict[str, Key]] = {}
for _k in KEYS:
    SCHEMA.setdefault(_k.section, {})[_k.name] = _k
"""section -> {key name: Key}: the TOML schema, derived from :data:`KEYS`."""
del _k
_MODEL_KEYS = {f.name for f in dataclasses.fields(ModelOptions)}


def _key_list() -> str:
    """The docstring's key list: one entry per key, from :data:`KEYS`."""
    lines = ["", "    Keys (``[section] key``: type (unit), default; allowed values)",
             "    " + "-" * 62]
    for key in KEYS:
        if key.default is not None:
            default = toml_value(key.default)
        else:
            default = toml_value(key.none_word) if key.none_word else "not set"
        kind = key.kind + (", or not set" if key.optional and not key.none_word else "")
        unit = f" ({key.unit})" if key.unit else ""
        rules = f"; {key.rules()}" if key.rules() else ""
        lines.append(f"    ``[{key.section}] {key.name}``: {kind}{unit}, default {default}{rules}")
        lines += textwrap.wrap(key.help, 88, initial_indent=" " * 8, subsequent_indent=" " * 8)
    return "\n".join(lines) + "\n"


def config_fields(config: SweepConfig) -> dict:
    """{field: value} of ``config``, every field but ``base_dir``."""
    return {f.name: getattr(config, f.name) for f in dataclasses.fields(config)
            if f.name != "base_dir"}


def config_sections(flat: dict) -> dict:
    """{field: value} (:func:`config_fields`) as the TOML structure: {section: {key: value}}
    and ``model`` (the options); None values left out."""
    out: dict = {}
    for key in KEYS:
        if key.field in flat and flat[key.field] is not None:
            value = flat[key.field]
            out.setdefault(key.section, {})[key.name] = (list(value) if isinstance(value, tuple)
                                                         else value)
    options = flat.get("options")
    if options is not None:
        out["model"] = options.as_dict() if isinstance(options, ModelOptions) else dict(options)
    return out


def _suggest(key: str, known) -> str:
    close = difflib.get_close_matches(key, list(known), n=1, cutoff=0.5)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _convert(key: Key, value, problems: list[str]):
    """Type-check one value; returns the converted value or None (problem recorded)."""
    where, kind = key.where, key.kind
    if key.none_word is not None and value == key.none_word:
        return None
    if kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            problems.append(f"{where} must be a whole number, got {value!r}")
            return None
        return int(value)
    if kind == "float":
        if not _is_number(value) or not math.isfinite(float(value)):
            if key.none_word is not None:
                problems.append(f"{where} must be a number ({key.unit}) or "
                                f"\"{key.none_word}\", got {value!r}")
            else:
                problems.append(f"{where} must be a finite number, got {value!r}")
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

    Raises :class:`~lfjax.sweep.config_keys.SweepConfigError` listing every problem.
    """
    problems: list[str] = []
    values: dict = {}
    if not isinstance(data, dict):
        raise SweepConfigError([f"expected a table of sections, got {type(data).__name__}"], source)
    known_sections = list(SCHEMA) + ["model"]
    for section, body in data.items():
        if section not in known_sections:
            problems.append(f"unknown section [{section}]{_suggest(section, known_sections)}; "
                            f"known: {', '.join(known_sections)}")
            continue
        if not isinstance(body, dict):
            problems.append(f"[{section}] must be a table of keys, got {body!r}")
            continue
        if section == "model":
            for key in body:
                if key not in _MODEL_KEYS:
                    problems.append(f"model.{key}: unknown model option{_suggest(key, _MODEL_KEYS)}"
                                    f"; known: {', '.join(sorted(_MODEL_KEYS))}")
            continue
        keys = SCHEMA[section]
        for name, value in body.items():
            if name not in keys:
                all_keys = {k.name for k in KEYS}
                hint = _suggest(name, keys) or _suggest(name, all_keys)
                problems.append(f"{section}.{name}: unknown key{hint}; known in [{section}]: "
                                f"{', '.join(keys)}")
                continue
            converted = _convert(keys[name], value, problems)
            if converted is not None or keys[name].none_word is not None:
                values[keys[name].field] = converted

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
    """Every impossible value or combination (the values' types are already right): each
    key's declared checks, then the checks that relate several keys."""
    p: list[str] = []
    failed = set()
    for key in KEYS:
        value = v[key.field]
        if value is None and key.optional:
            continue
        found = [problem for check in key.checks for problem in check(key, value, base_dir)]
        if found:
            failed.add(key.field)
            p += found
    return p + _combination_problems(v, failed, base_dir)


def _refused(where: str, check: Callable, *args, keys: dict | None = None, **kwargs) -> list[str]:
    """The problem a shared library check (one raising a
    :class:`~lfjax.base.errors.ParameterError`) finds, its parameter named as the key
    ``where`` (and other parameters as ``keys`` says); [] when it passes."""
    try:
        check(*args, **kwargs)
    except ParameterError as err:
        return [err.naming({**(keys or {}), err.parameter: where})]
    return []


def _combination_problems(v: dict, failed: set[str], base_dir: Path = Path(".")) -> list[str]:
    """The checks that relate several keys (``failed``: fields whose own checks failed)."""
    p: list[str] = []
    # the model's dioptric range (lfjax.base.units.check_dioptres, as every entry point)
    if "cdp_D" not in failed and v["cdp_D"] >= 0:
        p += _refused("display.cdp_D", check_dioptres, "cdp_D", v["cdp_D"], "CDP")
        if v["depth_offsets_D"] and "depth_offsets_D" not in failed:
            depths = [v["cdp_D"] + d for d in v["depth_offsets_D"]]
            if min(depths) >= -1e-9:  # below 0 D: said below
                p += _refused("display.depth_offsets_D", check_dioptres, "depth_offsets_D",
                              depths, "rendered depth", note="cdp_D + each offset")
    if "accommodation_max_D" not in failed:
        p += _refused("accommodation.max_D", check_dioptres, "max_D", v["accommodation_max_D"],
                      "accommodation state")
    # every view of a layout file must reach into every calculation pupil (the paper
    # layouts are made for each pupil); refused here, before anything is planned
    if "layouts" not in failed and "pupil_diameters_mm" not in failed:
        for entry in v["layouts"]:
            if entry in PAPER_LAYOUTS or strip_views(entry) is not None:
                continue
            path = Path(entry) if Path(entry).is_absolute() else Path(base_dir) / entry
            layout, _ = load_layout_json(path)
            for pupil in v["pupil_diameters_mm"]:
                p += _refused(f"display.layouts ({entry})", check_views_in_pupil,
                              layout.centres_mm, layout.diameters_mm, pupil, layout.name,
                              pupil_parameter="pupil_diameters_mm",
                              keys={"pupil_diameters_mm": "population.pupil_diameters_mm"})
    pupils, measured = v["pupil_diameters_mm"], v["measured_pupil_mm"]
    if "measured_pupil_mm" not in failed and pupils and all(d > 0 for d in pupils):
        limit = measured if measured is not None else max(THIBOS_PUPILS_MM)
        too_big = [d for d in pupils if d > limit + 1e-9]
        if too_big:
            p.append(f"population.pupil_diameters_mm {too_big} exceed the measured pupil "
                     f"({limit:g} mm): allowed range (0, {limit:g}] mm")
    aberrated = [k for k in ("lenslet_spherical_um", "lenslet_coma_um", "lenslet_astigmatism_um",
                             "lenslet_field_curvature_um") if v[k] != 0.0]
    strips = [e for e in v["layouts"] if isinstance(e, str) and strip_views(e) is not None]
    if aberrated and strips:
        p.append(f"display.{aberrated[0]} (and every lenslet_*_um key) must be 0 with 1xN strip "
                 f"layouts ({', '.join(strips)}): the lenslet aberrations "
                 f"(lfjax.display.aberrations) are of spherical lenslets over a view's disc or "
                 f"square, not of cylindrical lenticules over a strip; sweep the strips without "
                 f"them, or the aberrations with NxN layouts")
    cdp, offsets = v["cdp_D"], v["depth_offsets_D"]
    if offsets and any(cdp + d < -1e-9 for d in offsets):
        p.append(f"display.depth_offsets_D: every rendered depth cdp_D + offset must be >= 0 D; "
                 f"cdp_D = {cdp} with offsets {list(offsets)}")
    if offsets and "natural" in v["layouts"] and 0.0 not in [round(d, 9) for d in offsets]:
        p.append("display.depth_offsets_D must include 0 when layouts include 'natural' "
                 "(natural view is evaluated at the CDP)")
    step, top, window = v["accommodation_step_D"], v["accommodation_max_D"], v["window_D"]
    if "accommodation_step_D" not in failed and top > 0 and top / step > MAX_ACCOMMODATION_STATES:
        p.append(f"accommodation.step_D = {step:g} D makes {top / step:.3g} states on "
                 f"0 ... max_D = {top:g} D: at most {MAX_ACCOMMODATION_STATES} (step >= "
                 f"{top / MAX_ACCOMMODATION_STATES:.2g} D); continuous peaks "
                 f"(metrics.continuous_peaks) refine off the grid")
    if "window_D" not in failed and step > 0 and window < step:
        p.append(f"accommodation.window_D ({window} D) must be >= step_D ({step} D): a peak "
                 f"needs >= 2 states per depth")
    if offsets and top > 0 and cdp >= 0 and max(cdp + d for d in offsets) - window > top:
        p.append(f"accommodation.max_D ({top} D) leaves no state within window_D of the "
                 f"nearest rendered depth")
    wl = v["wavelengths_nm"]
    if len(wl) == 2 and v["display_spectrum"] is not None:
        p.append("spectrum.wavelengths_nm needs a step with spectrum.display (the step is the "
                 "width of the display spectrum's cells): [start, stop, step] in nm")
    if len(wl) in (2, 3):
        sce_on = v["options"].sce != "off"
        lo, hi = (400.0, 700.0) if sce_on else (390.0, 830.0)
        if wl[0] < lo - 1e-9 or wl[1] > hi + 1e-9:
            p.append(f"spectrum.wavelengths_nm must lie in [{lo:g}, {hi:g}] nm "
                     f"({'Stiles-Crawford data' if sce_on else 'luminous efficiency data'}), got "
                     f"{list(wl)}")
    distance = v["lenslet_distance_mm"]
    if distance is not None:
        limit = 1000.0 / cdp if cdp > 0 else math.inf
        if not (0 < distance < limit):
            p.append(f"display.lenslet_distance_mm must be in (0, {limit:.4g}) mm (the CDP is a "
                     f"virtual image behind the display), got {distance}")
    # the strip keys shape 1xN layouts only: set without one they would change nothing
    if not any(strip_views(e) is not None for e in v["layouts"]):
        for name, default in (("strip_width_ratio", 1.0), ("strip_y_defocus_D", 0.0)):
            if name not in failed and v[name] != default:
                p.append(f"display.{name} = {v[name]:g} shapes the 1xN strip layouts, but "
                         f"display.layouts has none (add one, e.g. \"1x3\", or leave it at "
                         f"{default:g})")
    if v["vsotf_tolerance"] is not None and v["freq_step_cpd"] is not None:
        p.append("sampling.vsotf_tolerance plans the frequency step: give it or "
                 "freq_step_cpd, not both")
    return p


SweepConfig.__doc__ += _key_list()


__all__ = [
    "config_fields",
    "config_from_dict",
    "config_sections",
    "KEYS",
    "SCHEMA",
    "SweepConfig",
]
