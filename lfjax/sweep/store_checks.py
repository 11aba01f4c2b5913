"""Whether a folder is a sweep store, and whether it can be trusted: its format, the
checksums of its chunks and of its configuration, its chunk bookkeeping, and its
configuration against a sweep's (:func:`check_store_matches`).

A store's chunk is marked complete (``chunk_complete``) only after its data are written,
with their checksum (``chunk_checksum``, :func:`chunk_checksum`); the configuration and
every array without an ``eye`` axis are covered by ``metadata_checksum``
(:func:`metadata_checksum`). :func:`verify_store` reads a store back against them and
reports every damage it finds. The store itself is written by :mod:`lfjax.sweep.store`.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path

import numpy as np

from lfjax._version import __version__
from lfjax.sweep.config import SweepConfig
from lfjax.sweep.config_files import config_differences, with_new_defaults

STORE_FORMAT = "lfjax-sweep-store/1"


CHECKSUM_SCHEME = 2
"""What the checksums of a store cover (its attribute ``checksum_scheme``): 2 — each chunk's
eye variables and its eyes' ``zernike_um``, and (attribute ``metadata_checksum``) the
configuration attributes and every array without an ``eye`` axis, with the ``eye`` and
``is_average`` coordinates; a store without the attribute (1) — the eye variables only."""


BOOKKEEPING = ("chunk_complete", "chunk_checksum")


_UNCHECKED_ATTRS = ("runs_json", "completed_utc", "metadata_checksum")  # change as runs end


ZARR_FORMAT = 2  # strings (layout names) have no stable Zarr v3 encoding yet (zarr 3.1 warns)


EYE_VARIABLES = (
    "vsotf", "strehl", "predicted_accommodation", "accommodation_error",
    "predicted_accommodation_continuous", "continuous_error", "continuous_peak_success",
    "peak_value", "cutoff_frequency", "mtf_at_peak",
)


class StoreMismatchError(ValueError):
    """A store made by another configuration (``differences``: one line each)."""

    def __init__(self, path, differences: list[str]):
        self.differences = differences
        lines = "\n".join(f"  - {d}" for d in differences)
        super().__init__(
            f"{path} was made by another sweep configuration; refusing to resume it. "
            f"Differences:\n{lines}\nRun with the store's own config (its attribute "
            f"'config_toml'), or write to another --out.")


def stored_record(config: SweepConfig) -> dict:
    """What a store records of the sweep that made it, and resumes against: the
    configuration (:meth:`~lfjax.sweep.config.SweepConfig.as_dict`) and the lfjax version."""
    return {"config": config.as_dict(), "lfjax_version": __version__}


def open_group(path, mode: str = "r"):
    """The store's Zarr group at ``path``, read through each array's own metadata."""
    import zarr

    # the arrays' own metadata, not .zmetadata: a damaged consolidated copy must not hide
    # an intact store (it is rewritten when a run ends, record_run)
    return zarr.open_group(str(path), mode=mode, zarr_format=ZARR_FORMAT, use_consolidated=False)


def one_line(err: BaseException, limit: int = 120) -> str:
    """``err`` as one line of at most ``limit`` characters after its type, for a report."""
    return f"{type(err).__name__}: {' '.join(str(err).split())[:limit]}"


def is_store(path) -> bool:
    """Whether ``path`` is a folder whose attributes say it is an lfjax sweep store."""
    path = Path(path)
    if not path.is_dir():
        return False
    try:
        return open_group(path).attrs.get("format") == STORE_FORMAT
    except Exception:  # noqa: BLE001 - any unreadable folder is "not a sweep store"
        return False


def store_damage(path) -> str | None:
    """Why ``path``, a folder with Zarr metadata files, cannot be read as a sweep store
    (a damaged ``.zattrs``/``.zgroup``), or None (a store, or no Zarr folder at all)."""
    path = Path(path)
    if not path.is_dir() or is_store(path):
        return None
    for name in (".zattrs", ".zgroup", ".zmetadata"):
        file = path / name
        if file.is_file():
            try:
                json.loads(file.read_text())
            except (OSError, ValueError) as err:
                return f"its metadata file {name} is damaged ({one_line(err)})"
    return None


def not_a_store(path) -> str:
    """The sentence refusing ``path`` as a sweep store: damaged, or not one at all."""
    damage = store_damage(path)
    if damage is not None:
        return f"{path} looks like an lfjax sweep store but {damage}; it cannot be read"
    return f"{path} is not an lfjax sweep store (format {STORE_FORMAT!r})"


def consolidated_damage(path) -> str | None:
    """Why the store's consolidated metadata (``.zmetadata``) cannot be read, or None."""
    file = Path(path) / ".zmetadata"
    if not file.is_file():
        return None
    try:
        json.loads(file.read_text())
    except (OSError, ValueError) as err:
        return f".zmetadata (the consolidated metadata) is damaged ({one_line(err)})"
    return None


class StoreDamagedError(ValueError):
    """A store's configuration or coordinates no longer match the checksum written with
    them (``metadata_checksum``): no chunk can be trusted to be computed as recorded."""


def metadata_checksum(group) -> int:
    """BLAKE2b-64 of a store's configuration attributes (all but ``runs_json``,
    ``completed_utc`` and itself, which change as runs end) and of every array without an
    ``eye`` axis, with the ``eye`` and ``is_average`` coordinates (names, dtypes, shapes and
    values); never 0. ``group``: the store's open Zarr group."""
    h = hashlib.blake2b(digest_size=8)
    attrs = {k: v for k, v in dict(group.attrs).items() if k not in _UNCHECKED_ATTRS}
    h.update(json.dumps(attrs, sort_keys=True).encode())
    for name in sorted(group.array_keys()):
        array = group[name]
        dims = array.attrs.get("_ARRAY_DIMENSIONS", [])
        if name in BOOKKEEPING or ("eye" in dims and name not in ("eye", "is_average")):
            continue
        a = np.asarray(array[...])
        if a.dtype.kind == "f":
            a = np.where(np.isnan(a), np.nan, a).astype(a.dtype)
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes() if a.dtype.kind not in "OUS" else json.dumps(a.tolist()).encode())
    return int.from_bytes(h.digest(), "little") or 1


def metadata_problem(path) -> str | None:
    """Why the store's configuration and coordinates cannot be trusted (they do not match
    ``metadata_checksum``, or cannot be read), or None (they match, or the store predates
    the checksum)."""
    try:
        group = open_group(path)
        stored = group.attrs.get("metadata_checksum")
        if stored is None:
            return None
        if metadata_checksum(group) != int(stored):
            return ("its configuration or coordinates do not match the checksum written with "
                    "them (attribute metadata_checksum): an attribute or a coordinate file was "
                    "altered")
    except Exception as err:  # noqa: BLE001 - any failure to read them is damage
        return f"its configuration or coordinates cannot be read ({one_line(err)})"
    return None


def check_store_matches(path, config: SweepConfig) -> None:
    """Raise :class:`StoreMismatchError` unless ``path`` was made by ``config`` and this
    lfjax version (a :class:`StoreDamagedError` when its recorded configuration fails its
    checksum)."""
    if not is_store(path):
        raise ValueError(f"{not_a_store(path)}; choose another --out")
    problem = metadata_problem(path)
    if problem is not None:
        raise StoreDamagedError(f"{path}: {problem}; it cannot be resumed safely (verify it "
                                f"with lfjax sweep {path} --verify; write a new store to "
                                f"another --out)")
    attrs = open_group(path).attrs
    # keys added since the store was written are at their defaults there (with_new_defaults)
    stored = {"config": with_new_defaults(json.loads(attrs["config_json"])),
              "lfjax_version": attrs["lfjax_version"]}
    current = json.loads(json.dumps(stored_record(config), sort_keys=True))
    differences = config_differences(stored, current)
    if differences:
        raise StoreMismatchError(path, differences)


@dataclasses.dataclass
class Bookkeeping:
    """A store's chunk marks as read back, each chunk's file alone when the whole array
    cannot be read.

    done : (n_chunks,) bool, marked complete (False where the mark cannot be trusted)
    sums : (n_chunks,) uint64, checksums written with them (0: none)
    damaged : {chunk: why} chunks whose marks are unreadable, missing or contradict each
        other (the bookkeeping file is named); they are recomputed on resume
    has_checksums : the store records checksums (a store from before them does not)
    """

    done: np.ndarray
    sums: np.ndarray
    damaged: dict
    has_checksums: bool


def _read_marks(group, name: str, n: int, dtype) -> tuple[np.ndarray, dict]:
    values = np.zeros(n, dtype)
    try:
        values[:] = np.asarray(group[name][:], dtype)
        return values, {}
    except Exception:  # noqa: BLE001 - read each chunk's file alone to name the damaged one
        pass
    broken = {}
    for i in range(n):
        try:
            values[i] = np.asarray(group[name][i], dtype)
        except Exception as err:  # noqa: BLE001 - a damaged file, whatever the decoder says
            broken[i] = f"bookkeeping file {name}/{i} is unreadable ({one_line(err, 80)})"
    return values, broken


def read_bookkeeping(path) -> Bookkeeping:
    """The store's :class:`Bookkeeping` (``chunk_complete`` and ``chunk_checksum``): a
    damaged or missing mark file is named, not raised. Marks are written complete first,
    checksum second, and unmarked in the same order: a chunk marked complete without a
    checksum, or with a checksum but not complete, has lost a bookkeeping file."""
    group = open_group(path)
    n = int(group["chunk_complete"].shape[0])
    done, damaged = _read_marks(group, "chunk_complete", n, bool)
    has_checksums = "chunk_checksum" in group
    sums = np.zeros(n, np.uint64)
    if has_checksums:
        sums, broken = _read_marks(group, "chunk_checksum", n, np.uint64)
        for i, why in broken.items():
            damaged[i] = f"{damaged[i]}; {why}" if i in damaged else why
        for i in range(n):
            if i in damaged:
                continue
            if done[i] and not sums[i]:
                damaged[i] = (f"bookkeeping file chunk_checksum/{i} is missing or altered (the "
                              f"chunk is marked complete without its checksum)")
            elif not done[i] and sums[i]:
                damaged[i] = (f"bookkeeping file chunk_complete/{i} is missing or altered (not "
                              f"marked complete, yet its checksum was written)")
    done = done & ~np.isin(np.arange(n), list(damaged))
    return Bookkeeping(done, sums, damaged, has_checksums)


def completed_chunks(path) -> np.ndarray:
    """(n_chunks,) bool: which chunks are written (a chunk whose marks are damaged is not:
    :func:`read_bookkeeping`)."""
    return read_bookkeeping(path).done


def chunk_checksum(part, zernike_um=None) -> int:
    """BLAKE2b-64 of a chunk's eye variables (name, dtype, shape and values; every NaN
    counted alike) and, when given (checksum scheme 2, :data:`CHECKSUM_SCHEME`), its eyes'
    ``zernike_um`` (n, n_modes) µm, as an unsigned 64-bit integer; never 0."""
    h = hashlib.blake2b(digest_size=8)
    arrays = [(name, np.asarray(part[name].values)) for name in sorted(EYE_VARIABLES)]
    if zernike_um is not None:
        arrays.append(("zernike_um", np.asarray(zernike_um, np.float64)))
    for name, a in arrays:
        if a.dtype.kind == "f":
            a = np.where(np.isnan(a), np.nan, a).astype(a.dtype)
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(np.ascontiguousarray(a).tobytes())
    return int.from_bytes(h.digest(), "little") or 1


@dataclasses.dataclass
class Verification:
    """What :func:`verify_store` found, chunk indices in each list.

    ok : complete and their data match the checksum
    corrupt : complete but their data are missing, unreadable or do not match, or their
        bookkeeping (``chunk_complete/<i>``, ``chunk_checksum/<i>``) is damaged ({i: why})
    unchecked : complete, written without a checksum (a store from before checksums)
    incomplete : not yet computed
    problems : damage to the store as a whole (its configuration or coordinates against
        their checksum, its consolidated metadata), one sentence each
    """

    ok: list[int]
    corrupt: dict[int, str]
    unchecked: list[int]
    incomplete: list[int]
    problems: list[str] = dataclasses.field(default_factory=list)

    @property
    def healthy(self) -> bool:
        return not self.corrupt and not self.problems

    def summary(self) -> str:
        n = len(self.ok) + len(self.corrupt) + len(self.unchecked) + len(self.incomplete)
        lines = [f"{len(self.ok)} of {n} chunks verified, {len(self.corrupt)} corrupt, "
                 f"{len(self.incomplete)} not computed"
                 + (f", {len(self.unchecked)} without checksum" if self.unchecked else "")]
        lines += [f"  store: {why}" for why in self.problems]
        lines += [f"  chunk {i}: {why}" for i, why in sorted(self.corrupt.items())]
        if self.corrupt:
            lines.append("  (lfjax sweep CONFIG --out STORE --resume recomputes them)")
        return "\n".join(lines)


def verify_store(path, chunks=None) -> Verification:
    """Read every complete chunk (or those in ``chunks``) back from the store and compare it
    with the checksum written with it; check the chunk marks themselves
    (:func:`read_bookkeeping`), the configuration and coordinates against
    ``metadata_checksum`` and the consolidated metadata. A deleted chunk file reads as fill
    values (NaN) and a truncated one fails to decode: both are reported corrupt, naming the
    reason. Reports every damage it finds and raises only for a path that is no sweep store
    (ValueError, :func:`not_a_store`)."""
    import xarray as xr

    path = Path(path)
    if not is_store(path):
        raise ValueError(not_a_store(path))
    result = Verification([], {}, [], [])
    for problem in (consolidated_damage(path), metadata_problem(path)):
        if problem is not None:
            result.problems.append(problem)
    try:
        marks = read_bookkeeping(path)
        attrs = open_group(path).attrs
        size = int(attrs["chunk_size"])
        with_zernike = int(attrs.get("checksum_scheme", 1)) >= 2
        ds = xr.open_zarr(str(path), consolidated=False, zarr_format=ZARR_FORMAT)
        n_eye = ds.sizes["eye"]
    except Exception as err:  # noqa: BLE001 - report, never raise
        result.problems.append(f"its chunk bookkeeping cannot be read ({one_line(err)})")
        return result
    names = list(EYE_VARIABLES) + (["zernike_um"] if with_zernike else [])
    for i in range(marks.done.size) if chunks is None else chunks:
        if i in marks.damaged:
            result.corrupt[i] = marks.damaged[i]
            continue
        if not marks.done[i]:
            result.incomplete.append(i)
            continue
        if not marks.sums[i]:
            result.unchecked.append(i)
            continue
        start, stop = i * size, min((i + 1) * size, n_eye)
        try:
            part = ds[names].isel(eye=slice(start, stop)).load()
        except Exception as err:  # noqa: BLE001 - any decode failure means corrupt data
            result.corrupt[i] = f"unreadable ({one_line(err)})"
            continue
        why = chunk_mismatch(part, int(marks.sums[i]), with_zernike)
        if why is not None:
            result.corrupt[i] = why
            continue
        result.ok.append(i)
    return result


def chunk_mismatch(part, checksum: int, with_zernike: bool) -> str | None:
    """Why a chunk's data ``part`` (its eyes of the :data:`EYE_VARIABLES`, with
    ``zernike_um`` when ``with_zernike``) do not match the ``checksum`` written with them,
    or None when they do."""
    zernike = part["zernike_um"].values if with_zernike else None
    if chunk_checksum(part, zernike) != checksum:
        return ("data do not match the checksum written with them (a chunk file missing or "
                "altered, its eyes' zernike_um among them)")
    return None


class StoreCorruptError(ValueError):
    """A store that :func:`verify_store` would not pass (``verification``: what it found),
    read by something that must not use its numbers (``lfjax sweep-report``)."""

    def __init__(self, path, verification: Verification):
        self.verification = verification
        v = verification
        damage = [f"store: {why}" for why in v.problems]
        damage += [f"chunk {i}: {why}" for i, why in sorted(v.corrupt.items())]
        if any(why.startswith("its configuration or coordinates") for why in v.problems):
            fix = ("Its configuration cannot be trusted, so it cannot be resumed: run the "
                   "sweep again into another --out")
        else:
            fix = (f"Repair it with lfjax sweep CONFIG.toml --out {path} --resume (it "
                   f"recomputes the damaged chunks; CONFIG.toml: the sweep's own "
                   f"configuration, kept in the store's attribute config_toml)")
        super().__init__(f"{path} fails verification (what lfjax sweep --verify checks): "
                         + "; ".join(damage) + f". {fix}")


__all__ = [
    "BOOKKEEPING",
    "Bookkeeping",
    "check_store_matches",
    "CHECKSUM_SCHEME",
    "chunk_checksum",
    "chunk_mismatch",
    "completed_chunks",
    "consolidated_damage",
    "EYE_VARIABLES",
    "is_store",
    "metadata_checksum",
    "metadata_problem",
    "not_a_store",
    "one_line",
    "open_group",
    "read_bookkeeping",
    "store_damage",
    "STORE_FORMAT",
    "stored_record",
    "StoreCorruptError",
    "StoreDamagedError",
    "StoreMismatchError",
    "Verification",
    "verify_store",
    "ZARR_FORMAT",
]
