"""The vocabulary a sweep's keys are declared in: :class:`Key` (a TOML key, on its
:class:`~lfjax.sweep.config.SweepConfig` field), the checks of one value (:class:`Range`,
:class:`OneOf`, :class:`NonEmpty`, :class:`Distinct`, the layout entries and the wavelength
grid), the units in key names (:data:`UNIT_SUFFIXES`), the limits of a sweep and
:class:`SweepConfigError`, which lists every problem found at once.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from lfjax.model.layout_files import load_layout_json
from lfjax.model.layouts import PAPER_LAYOUTS

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


MAX_STRIP_VIEWS = 16
"""Most strips of a ``1xN`` layout entry: 16 strips fill a 3 mm pupil every 0.19 mm, far
below the paper's finest view pitch (0.75 mm); the frequency grid such narrow strips need
grows with N."""


MAX_STRIP_WIDTH_RATIO = 2.0
"""Widest strip of a ``1xN`` layout, as a multiple of its pitch: at 2 a strip reaches its
neighbours' centres (the overlap scans of :mod:`lfjax.studies.hpo` stop there too)."""


def strip_views(entry: str) -> int | None:
    """N of a ``1xN`` strip-layout entry of ``display.layouts`` (an HPO layout of N
    vertical strips across each pupil), or None for any other entry."""
    if not (isinstance(entry, str) and entry.startswith("1x") and entry[2:].isdigit()
            and entry[2:] == str(int(entry[2:]))):
        return None
    return int(entry[2:])


UNIT_SUFFIXES = {"_D": "dioptres", "_mm": "millimetres", "_nm": "nanometres",
                 "_cpd": "cycles per degree", "_arcmin": "arcminutes", "_um": "micrometres"}
"""A key's unit is the suffix of its name (``cdp_D`` is in D); a key without one has none."""


class SweepConfigError(ValueError):
    """A sweep configuration with one or more problems (``problems``: one string each)."""

    def __init__(self, problems: list[str], source: str = "sweep config"):
        self.problems = list(problems)
        lines = "\n".join(f"  - {p}" for p in self.problems)
        super().__init__(f"{source}: {len(self.problems)} problem(s):\n{lines}")


@dataclass(frozen=True)
class Key:
    """One key of the TOML file, declared on its
    :class:`~lfjax.sweep.config.SweepConfig` field.

    Written in the field's metadata: ``section``, ``help``, ``checks``, and where needed
    ``name``, ``example`` and ``none_word``; taken from the field itself: ``field``,
    ``kind`` and ``optional`` (its annotation), ``default``; from the name: ``unit``.

    Attributes
    ----------
    section : the TOML table it stands in (``[population]``, …)
    help : what it sets, one line (the template's comment, the docstring's key list)
    checks : rules on the value alone, each a callable ``check(key, value, base_dir)``
        returning the problems it finds (``Range``, ``OneOf``, ``NonEmpty``, ``Distinct``
        or a function); a key's every check runs, so all its problems are listed at once
    name : the key in its table (default: the field's name)
    example : a value the template shows, commented out, for a key not set by default
    none_word : the TOML word that means None where None means something
        (``freq_step_cpd = "planned"``); other optional keys are simply left out
    field : the :class:`~lfjax.sweep.config.SweepConfig` field it sets
    kind : its TOML type: ``int``, ``float``, ``bool``, ``string``, ``floats`` or ``strings``
    optional : None is a valid value (the annotation is ``X | None``)
    default : the field's default
    unit : from the name's suffix (:data:`UNIT_SUFFIXES`), "" if none
    """

    section: str
    help: str
    checks: tuple = ()
    name: str = ""
    example: object = None
    none_word: str | None = None
    field: str = ""
    kind: str = ""
    optional: bool = False
    default: object = None
    unit: str = ""

    @property
    def where(self) -> str:
        """``section.name``, as problems name the key."""
        return f"{self.section}.{self.name}"

    def rules(self) -> str:
        """The allowed values in words ("" when no check describes itself)."""
        described = [c.rule(self.unit) for c in self.checks if hasattr(c, "rule")]
        return "; ".join(r for r in described if r)


def key_metadata(section: str, help: str, *checks, name: str = "", example=None,
         none_word: str | None = None) -> dict:
    """Field metadata declaring a TOML key (the rest of :class:`Key` comes from the field)."""
    return {"sweep_key": Key(section, help, tuple(checks), name, example, none_word)}


def shown(value):
    """``value`` as a problem or a record shows it (a tuple as a list, as TOML and JSON do)."""
    return list(value) if isinstance(value, tuple) else value


@dataclass(frozen=True)
class Range:
    """The interval a number (or every number of a list) must lie in.

    ``text`` writes the interval where ``:g`` would not (``[0, 2**32)``); ``note`` says why,
    in parentheses after it; ``tol`` lets values this close outside it pass (rounding)."""

    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    text: str | None = None
    note: str = ""
    tol: float = 0.0

    def rule(self, unit: str = "") -> str:
        if self.text is not None:
            body = f"in {self.text}"
        elif self.lo is not None and self.hi is not None:
            body = (f"in {'(' if self.lo_open else '['}{self.lo:g}, "
                    f"{self.hi:g}{')' if self.hi_open else ']'}")
        elif self.lo is not None:
            body = f"{'>' if self.lo_open else '>='} {self.lo:g}"
        else:
            body = f"{'<' if self.hi_open else '<='} {self.hi:g}"
        return f"{body} {unit}".rstrip()

    def holds(self, x) -> bool:
        if self.lo is not None and not (x > self.lo - self.tol if self.lo_open
                                        else x >= self.lo - self.tol):
            return False
        return self.hi is None or (x < self.hi + self.tol if self.hi_open
                                   else x <= self.hi + self.tol)

    def __call__(self, key: Key, value, base_dir: Path) -> list[str]:
        values = value if isinstance(value, tuple) else (value,)
        if all(self.holds(x) for x in values):
            return []
        notes = [n for n in (self.note, key.none_word and f'or "{key.none_word}"') if n]
        why = "".join(f" ({n})" for n in notes)
        return [f"{key.where} must be {self.rule(key.unit)}{why}, got {shown(value)}"]


@dataclass(frozen=True)
class OneOf:
    """The values a key (or every entry of a list key) may take; ``note`` says why."""

    choices: tuple
    note: str = ""

    def listed(self, unit: str = "") -> str:
        if all(isinstance(c, str) for c in self.choices):
            return ", ".join(self.choices)
        return f"{list(self.choices)} {unit}".rstrip()

    def rule(self, unit: str = "") -> str:
        return f"one of {self.listed(unit)}"

    def __call__(self, key: Key, value, base_dir: Path) -> list[str]:
        why = f" ({self.note})" if self.note else ""
        if isinstance(value, tuple):
            bad = [x for x in value if x not in self.choices]
            return [f"{key.where} must list only {self.listed(key.unit)}{why}, got {bad}"
                    ] if bad else []
        if value in self.choices:
            return []
        return [f"{key.where} must be {self.rule(key.unit)}{why}, got {value!r}"]


@dataclass(frozen=True)
class NonEmpty:
    """A list key must hold at least one ``what``."""

    what: str

    def __call__(self, key: Key, value, base_dir: Path) -> list[str]:
        return [] if value else [f"{key.where} must list at least one {self.what}"]


@dataclass(frozen=True)
class Distinct:
    """A list key holds no value twice (numbers compared to 1e-9)."""

    def __call__(self, key: Key, value, base_dir: Path) -> list[str]:
        seen = [round(x, 9) if isinstance(x, float) else x for x in value]
        return [] if len(set(seen)) == len(seen) else [
            f"{key.where} has repeated values: {list(value)}"]


def check_layout_entries(key: Key, layouts, base_dir: Path) -> list[str]:
    """Each entry is a paper layout or a readable layout JSON file."""
    p = []
    for entry in layouts:
        if entry in PAPER_LAYOUTS:
            continue
        n = strip_views(entry)
        if n is not None:
            if not 1 <= n <= MAX_STRIP_VIEWS:
                p.append(f"{key.where}: {entry!r} must have 1 to {MAX_STRIP_VIEWS} strips "
                         f"(1x1 ... 1x{MAX_STRIP_VIEWS}), got {n}")
            continue
        if not entry.endswith(".json"):
            p.append(f"{key.where}: {entry!r} is neither a paper layout "
                     f"({', '.join(PAPER_LAYOUTS)}), a strip layout 1xN (N = 1 ... "
                     f"{MAX_STRIP_VIEWS}) nor a .json layout file")
            continue
        path = Path(entry) if Path(entry).is_absolute() else base_dir / entry
        if not path.is_file():
            p.append(f"{key.where}: layout file {str(path)!r} does not exist")
            continue
        try:
            load_layout_json(path)
        except (ValueError, OSError, json.JSONDecodeError) as err:
            p.append(f"{key.where}: {path}: {err}")
    return p


def check_wavelength_grid(key: Key, wl, base_dir: Path) -> list[str]:
    """[start, stop] or [start, stop, step], increasing, the step no finer than the data."""
    if len(wl) not in (2, 3):
        return [f"{key.where} must be [start, stop] (step planned) or [start, stop, step] in "
                f"nm, got {list(wl)}"]
    start, stop, step = wl if len(wl) == 3 else (*wl, 5.0)
    if not (step > 0 and stop >= start):
        return [f"{key.where}: need step > 0 and stop >= start, got {list(wl)}"]
    if step < MIN_WAVELENGTH_STEP_NM - 1e-12:
        return [f"{key.where} step must be >= {MIN_WAVELENGTH_STEP_NM:g} nm (the tabulation "
                f"interval of the luminous-efficiency data; a finer step only interpolates), "
                f"got {step:g} nm ({(stop - start) / step + 1:.3g} wavelengths)"]
    return []


def toml_value(value) -> str:
    """``value`` (bool, str, number or a list of them) as TOML text."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in value) + "]"
    return repr(value)


__all__ = [
    "check_layout_entries",
    "check_wavelength_grid",
    "CONFIG_FORMAT",
    "Distinct",
    "Key",
    "key_metadata",
    "MAX_ACCOMMODATION_STATES",
    "MAX_STRIP_VIEWS",
    "MAX_STRIP_WIDTH_RATIO",
    "MIN_PUPIL_MM",
    "MIN_WAVELENGTH_STEP_NM",
    "NonEmpty",
    "OneOf",
    "Range",
    "shown",
    "strip_views",
    "SweepConfigError",
    "toml_value",
    "UNIT_SUFFIXES",
]
