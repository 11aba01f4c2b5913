"""A sweep's results on disk: one labelled xarray Dataset in a Zarr store, written by chunks.

The store is created whole before any compute (NaN where nothing is computed yet; empty
Zarr chunks take no space), in a temporary folder renamed into place, so a store either
exists with its full metadata or not at all. Each chunk of eyes is then written into its
own region of the ``eye`` axis — the Zarr chunking along ``eye`` equals the compute chunk,
so no two writers (processes) ever touch the same file — and only after its data is written
is the chunk marked in ``chunk_complete``, with the checksum of what was written in
``chunk_checksum``. A chunk interrupted half-way is therefore unmarked and recomputed on
resume; a finished one is recomputed only when its data no longer match its checksum
(:func:`verify_store`). One writer at a time holds :class:`StoreLock` (``STORE.lock``).
The metadata are consolidated, and the attributes record the provenance.

Dataset (dims ``eye, pupil, layout, depth, accommodation, metric, frequency, zernike_j,
chunk``), see :func:`template` for every variable's units. :func:`study_view` presents one
pupil of a store as the reproduction's study Dataset, so the paper's claims
(:func:`lfjax.vision.claims.evaluate_claims`) run on any subset of its eyes.
"""

from __future__ import annotations

import dataclasses
import errno
import hashlib
import json
import os
import shutil
import socket
import warnings
from pathlib import Path

import numpy as np

from lfjax.base.files import (owned_temp_dir, pid_alive, register_emergency_cleanup,
                              remove_orphans, unregister_emergency_cleanup)
from lfjax._version import __version__, stamp, utc_now
from lfjax.vision.peaks import METRICS
from lfjax.base.sampling import Sampling
from lfjax.model.spectral import make_spectrum
from lfjax.sweep.compute import (FREQUENCIES_CPD, Task, layout_name, spectral_plans,
                                 sweep_spectra)
from lfjax.sweep.config import SweepConfig, config_differences, config_to_toml, with_new_defaults

STORE_FORMAT = "lfjax-sweep-store/1"
CHECKSUM_SCHEME = 2
"""What the checksums of a store cover (its attribute ``checksum_scheme``): 2 — each chunk's
eye variables and its eyes' ``zernike_um``, and (attribute ``metadata_checksum``) the
configuration attributes and every array without an ``eye`` axis, with the ``eye`` and
``is_average`` coordinates; a store without the attribute (1) — the eye variables only."""
BOOKKEEPING = ("chunk_complete", "chunk_checksum")
_UNCHECKED_ATTRS = ("runs_json", "completed_utc", "metadata_checksum")  # change as runs end
ZARR_FORMAT = 2  # strings (layout names) have no stable Zarr v3 encoding yet (zarr 3.1 warns)

_EYE_VARIABLES = (
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


def _stored_record(config: SweepConfig) -> dict:
    return {"config": config.as_dict(), "lfjax_version": __version__}


def spectral_record(config: SweepConfig, tasks: list[Task]) -> dict[str, dict]:
    """Each (pupil, layout)'s spectrum as the store records it (``spectra_json``), keyed
    ``"pupil_index,layout_index"``: ``rule`` — ``"gauss"`` (the Gauss rule for V(λ), planned),
    ``"uniform"`` (a planned step), ``"given"`` (the config's step) or ``"display"`` (a
    display's white) —, ``n_wavelengths``, ``step_nm`` (uniform rules, else None),
    ``wavelengths_nm`` and ``weights`` (summing to 1) as the pipeline sums them, and ``reason``
    (the planner's, for a planned rule)."""
    planned = config.wavelength_step_planned and config.display_spectrum is None
    plans = spectral_plans(config) if planned else {}
    spectra = sweep_spectra(config) if any(t.spectrum is None for t in tasks) else {}
    out = {}
    for t in tasks:
        spectrum = t.spectrum if t.spectrum is not None else spectra[t.key]
        wl = [float(w) for w in np.asarray(spectrum.wavelengths_nm)]
        plan = plans.get(t.key)
        if plan is not None:
            rule = plan.spectral_rule
            reason = " ".join(r for r in plan.reasons if r.startswith("wavelength"))
        else:
            rule = "display" if config.display_spectrum is not None else "given"
            reason = ("the display's white" if rule == "display"
                      else "the step given in spectrum.wavelengths_nm")
        uniform = rule != "gauss" and len(wl) > 1 and np.allclose(np.diff(wl), wl[1] - wl[0])
        out[f"{t.pupil_index},{t.layout_index}"] = {
            "rule": rule, "n_wavelengths": len(wl),
            "step_nm": float(wl[1] - wl[0]) if uniform else None,
            "wavelengths_nm": wl,
            "weights": [float(w) for w in np.asarray(spectrum.weights)],
            "reason": reason,
        }
    return out


def template(config: SweepConfig, tasks: list[Task], zernike_um, is_average) -> "xr.Dataset":  # noqa: F821
    """The store as an xarray Dataset before any chunk is computed, for the eyes given
    (``zernike_um`` (n, n_modes) µm, ``is_average`` (n,)): all of them, or the first chunk's
    when :func:`create_store` extends the eye axis to the population (``eyes``), so that
    creating a store takes memory of one chunk, not of the whole population."""
    import xarray as xr

    n_eye = int(np.shape(zernike_um)[0])
    n_pupil, n_layout = len(config.pupil_diameters_mm), len(config.layouts)
    depths = config.depths_D
    acc = config.accommodation_D
    base = (n_eye, n_pupil, n_layout, depths.size)
    dims5 = ("eye", "pupil", "layout", "depth")
    nan = lambda shape, dtype=np.float32: np.full(shape, np.nan, dtype)  # noqa: E731
    per_metric = base + (len(METRICS),)
    steps = np.full((n_pupil, n_layout), np.nan)
    n_fft = np.zeros((n_pupil, n_layout), np.int32)
    n_sub = np.zeros((n_pupil, n_layout), np.int32)
    sub_diam = np.full((n_pupil, n_layout), np.nan)
    samplings = {}
    spectra = spectral_record(config, tasks)
    n_wl = np.zeros((n_pupil, n_layout), np.int32)
    for t in tasks:
        n_wl[t.key] = spectra[f"{t.pupil_index},{t.layout_index}"]["n_wavelengths"]
        steps[t.key] = t.sampling.freq_step_cpd
        n_fft[t.key] = t.pipeline_config.n_fft
        n_sub[t.key] = t.layout.n_subapertures
        sub_diam[t.key] = float(np.max(np.asarray(t.layout.diameters_mm)))
        samplings[f"{t.pupil_index},{t.layout_index}"] = dataclasses.asdict(t.sampling)
    record = _stored_record(config)
    made = stamp()  # who made the store (provenance_json); the version also heads the attrs
    attrs = {
        "title": "lfjax population sweep: eyes viewing a light-field display",
        "format": STORE_FORMAT,
        "lfjax_version": record["lfjax_version"],
        "jax_version": made["jax_version"],
        "config_json": json.dumps(record["config"], sort_keys=True),
        "config_toml": config_to_toml(config),
        "model_options_json": json.dumps(config.options.as_dict(), sort_keys=True),
        "sampling_json": json.dumps(samplings, sort_keys=True),
        "units": "depths and accommodation in dioptres (D, absolute 1/m; 0 D = infinity); "
                 "frequency in cycles per degree (cpd); pupils and subapertures in mm; "
                 "Zernike coefficients in um",
        "eyes_source": "Thibos, Bradley & Hong (2002) statistics, lfjax.sample_eyes(seed, n) "
                       "on the measured pupil; the average eye (if any) is the last eye",
        # what the reproduction's claims read (lfjax.vision.claims)
        "cdp_D": float(config.cdp_D),
        "measured_pupil_mm": float(config.fit_pupil_mm),
        "config_cutoff_threshold": float(config.cutoff_threshold),
        "config_dof_fraction": float(config.dof_fraction),
        # every wavelength any (pupil, layout) sums; each one's own rule in spectra_json
        "wavelengths_nm": json.dumps(sorted({w for r in spectra.values()
                                             for w in r["wavelengths_nm"]})),
        "spectra_json": json.dumps(spectra, sort_keys=True),
        "display": json.dumps({"lenslet_distance_mm": config.lenslet_distance_mm,
                               "pixel_width_arcmin": config.pixel_width_arcmin,
                               **({} if config.lenslet_aberration() is None else {
                                   "lenslet_aberration_um": [
                                       config.lenslet_spherical_um, config.lenslet_coma_um,
                                       config.lenslet_astigmatism_um,
                                       config.lenslet_field_curvature_um]}),
                               # recorded only when set: the stores before them read the same
                               **({} if config.strip_width_ratio == 1.0 else {
                                   "strip_width_ratio": config.strip_width_ratio}),
                               **({} if config.strip_y_defocus_D == 0.0 else {
                                   "strip_y_defocus_D": config.strip_y_defocus_D}),
                               **({} if config.leakage_weight == 0.0 else {
                                   "leakage_weight": config.leakage_weight}),
                               "spectrum": config.display_spectrum or "V(lambda) white"}),
        "n_chunks": int(config.n_chunks),
        "chunk_size": int(config.chunk_size),
        "checksum_scheme": CHECKSUM_SCHEME,
        "provenance_json": json.dumps(made, sort_keys=True),
    }
    metric_note = "metric axis: vsotf, strehl"
    ds = xr.Dataset(
        data_vars=dict(
            vsotf=(dims5 + ("accommodation",), nan(base + (acc.size,)), {
                "long_name": "visual Strehl ratio computed from the OTF (VSOTF); NaN outside "
                             "each depth's window and, for natural view, off the CDP",
                "units": "1"}),
            strehl=(dims5 + ("accommodation",), nan(base + (acc.size,)), {
                "long_name": "Strehl ratio (PSF peak / reference PSF peak)", "units": "1"}),
            predicted_accommodation=(dims5 + ("metric",), nan(per_metric, np.float64), {
                "long_name": f"accommodation state maximising the metric on the grid "
                             f"({metric_note})", "units": "D"}),
            accommodation_error=(dims5 + ("metric",), nan(per_metric, np.float64), {
                "long_name": "grid predicted accommodation minus rendered depth (negative: "
                             "focused farther than the image)", "units": "D"}),
            predicted_accommodation_continuous=(dims5 + ("metric",), nan(per_metric, np.float64), {
                "long_name": f"continuous peak refined from the grid (lfjax.vision.peaks "
                             f"{config.peak_method!r}); NaN for metrics not in "
                             f"continuous_peaks", "units": "D"}),
            continuous_error=(dims5 + ("metric",), nan(per_metric, np.float64), {
                "long_name": "continuous predicted accommodation minus rendered depth",
                "units": "D"}),
            continuous_peak_success=(dims5 + ("metric",), np.zeros(per_metric, bool), {
                "long_name": "the continuous peak converged inside its bracket"}),
            peak_value=(dims5 + ("metric",), nan(per_metric), {
                "long_name": "metric value at its grid peak", "units": "1"}),
            cutoff_frequency=(dims5 + ("metric",), nan(per_metric), {
                "long_name": f"frequency where the radial MTF at the grid-predicted "
                             f"accommodation falls to {config.cutoff_threshold:g}",
                "units": "cpd"}),
            mtf_at_peak=(dims5 + ("metric", "frequency"), nan(per_metric + (FREQUENCIES_CPD.size,)), {
                "long_name": "radial (meridian-averaged) MTF at the grid-predicted "
                             "accommodation", "units": "1"}),
            zernike_um=(("eye", "zernike_j"), np.asarray(zernike_um, float), {
                "long_name": "OSA/ANSI Zernike coefficients on the measured pupil "
                             "(piston and tilt zeroed)", "units": "um"}),
            freq_step_cpd=(("pupil", "layout"), steps, {
                "long_name": "frequency step of the OTF grid (PSF field 60/df arcmin)",
                "units": "cpd"}),
            n_fft=(("pupil", "layout"), n_fft, {"long_name": "FFT size of the OTF grid"}),
            n_wavelengths=(("pupil", "layout"), n_wl, {
                "long_name": "wavelengths summed (the rule, its nodes and weights: attribute "
                             "spectra_json)"}),
            chunk_complete=(("chunk",), np.zeros(config.n_chunks, bool), {
                "long_name": "the chunk's eyes are written (eyes chunk*chunk_size …)"}),
            chunk_checksum=(("chunk",), np.zeros(config.n_chunks, np.uint64), {
                "long_name": "BLAKE2b-64 of the chunk's eye variables and its eyes' "
                             "zernike_um as written (lfjax.sweep.store.chunk_checksum; 0: not "
                             "written); the configuration and the other arrays: attribute "
                             "metadata_checksum"}),
        ),
        coords=dict(
            eye=("eye", np.arange(n_eye)),
            is_average=("eye", np.asarray(is_average, bool),
                        {"long_name": "the Thibos et al. (2002) average eye"}),
            pupil=("pupil", np.asarray(config.pupil_diameters_mm, float),
                   {"long_name": "calculation pupil diameter", "units": "mm"}),
            layout=("layout", [layout_name(e) for e in config.layouts]),
            layout_entry=("layout", list(config.layouts)),
            n_subapertures=(("pupil", "layout"), n_sub),
            subaperture_diameter_mm=(("pupil", "layout"), sub_diam, {"units": "mm"}),
            depth=("depth", depths, {"long_name": "rendered depth (absolute)", "units": "D"}),
            depth_rel_cdp=("depth", np.round(depths - config.cdp_D, 9), {
                "long_name": "rendered depth relative to the CDP", "units": "D"}),
            accommodation=("accommodation", acc, {
                "long_name": "absolute accommodation state 1/z_acc", "units": "D"}),
            metric=("metric", list(METRICS)),
            frequency=("frequency", FREQUENCIES_CPD, {"long_name": "spatial frequency",
                                                      "units": "cpd"}),
            zernike_j=("zernike_j", np.arange(np.shape(zernike_um)[1])),
            chunk=("chunk", np.arange(config.n_chunks)),
        ),
        attrs=attrs,
    )
    return ds


def record_run(path, started_utc: str, computed: list[int]) -> None:
    """Append this run (host, PID, start and end, chunks computed) to the store's
    ``runs_json`` attribute, mark ``completed_utc`` once every chunk is written, and
    re-consolidate the metadata. Process 0 only (attributes are one file)."""
    import zarr

    group = _open_group(path, "r+")
    runs = json.loads(group.attrs.get("runs_json", "[]"))
    runs.append({"host": socket.gethostname(), "pid": os.getpid(), "started_utc": started_utc,
                 "ended_utc": utc_now(), "chunks_computed": len(computed)})
    update = {"runs_json": json.dumps(runs)}
    if read_bookkeeping(path).done.all():
        update["completed_utc"] = runs[-1]["ended_utc"]
    group.attrs.update(update)
    zarr.consolidate_metadata(str(path), zarr_format=ZARR_FORMAT)


def stored_attribute(path, name: str, default=None):
    """The store's attribute ``name`` (``default`` when it has none)."""
    return _open_group(path).attrs.get(name, default)


def stored_samplings(path) -> dict:
    """{(pupil_index, layout_index): Sampling} recorded in a store."""
    attrs = _open_group(path).attrs
    out = {}
    for key, value in json.loads(attrs["sampling_json"]).items():
        pi, li = (int(x) for x in key.split(","))
        out[(pi, li)] = Sampling(**value)
    return out


def stored_spectra(path, config: SweepConfig) -> dict | None:
    """{(pupil_index, layout_index): Spectrum} a store's chunks were computed with, so a
    resumed sweep sums exactly those (not a rule planned again by other code): from
    ``spectra_json``, or, for a store made before rules were planned per layout, its one
    ``wavelengths_nm`` grid with V(λ) weights. None for a display's spectrum without
    ``spectra_json`` (the config derives it as it did)."""
    attrs = _open_group(path).attrs
    if "spectra_json" in attrs:
        return {tuple(int(x) for x in key.split(",")): make_spectrum(
                    np.asarray(r["wavelengths_nm"]), config.options, weights=np.asarray(r["weights"]))
                for key, r in json.loads(attrs["spectra_json"]).items()}
    if config.display_spectrum is not None or "wavelengths_nm" not in attrs:
        return None
    shared = make_spectrum(np.asarray(json.loads(attrs["wavelengths_nm"])), config.options)
    return {(pi, li): shared for pi in range(len(config.pupil_diameters_mm))
            for li in range(len(config.layouts))}


def _encoding(ds, chunk_size: int, n_eye: int | None = None) -> dict:
    enc = {}
    if n_eye is not None:  # the eye coordinates in one chunk, after create_store resizes them
        enc["eye"] = {"chunks": (int(n_eye),)}
        enc["is_average"] = {"chunks": (int(n_eye),)}
    for name, var in ds.data_vars.items():
        if "eye" in var.dims:
            enc[name] = {"chunks": tuple(chunk_size if d == "eye" else n
                                         for d, n in zip(var.dims, var.shape))}
        elif name in ("chunk_complete", "chunk_checksum"):
            enc[name] = {"chunks": (1,)}
    return enc


def create_store(path, ds, chunk_size: int, eyes=None) -> Path:
    """Write the template ``ds`` at ``path`` atomically (temporary folder, then rename).

    ``eyes`` = (zernike_um (n, n_modes), is_average (n,)) of the whole population when
    ``ds`` holds only its first eyes: the eye axis of every array is then extended to n
    (unwritten chunks read as the fill value, NaN) and the eyes' coefficients written, so
    the population's result arrays are never held in memory.
    """
    import zarr

    path = Path(path)
    if path.exists():
        raise FileExistsError(f"{path} already exists")
    path.parent.mkdir(parents=True, exist_ok=True)
    clean_interrupted_creations(path)
    tmp = owned_temp_dir(path.parent, f".{path.name}.creating")
    tmp.rmdir()  # to_zarr(mode="w-") creates it
    n_eye = None if eyes is None else int(np.shape(eyes[0])[0])
    try:
        ds.to_zarr(tmp, mode="w-", encoding=_encoding(ds, chunk_size, n_eye),
                   zarr_format=ZARR_FORMAT, consolidated=n_eye is None)
        if n_eye is not None and n_eye != ds.sizes["eye"]:
            group = zarr.open_group(str(tmp), mode="r+", zarr_format=ZARR_FORMAT)
            for name in list(ds.variables):
                dims = ds[name].dims
                if "eye" in dims:
                    array = group[name]
                    array.resize(tuple(n_eye if d == "eye" else n
                                       for d, n in zip(dims, array.shape)))
            group["eye"][:] = np.arange(n_eye)
            group["is_average"][:] = np.asarray(eyes[1], bool)
            group["zernike_um"][:] = np.asarray(eyes[0], float)
        group = zarr.open_group(str(tmp), mode="r+", zarr_format=ZARR_FORMAT,
                                use_consolidated=False)
        group.attrs["metadata_checksum"] = str(metadata_checksum(group))
        zarr.consolidate_metadata(str(tmp), zarr_format=ZARR_FORMAT)
        try:
            os.replace(tmp, path)
        except OSError as err:
            if err.errno not in (errno.ENOTEMPTY, errno.EEXIST) and not path.exists():
                raise
            # another process created it between the check above and this rename
            raise StoreRaceError(path) from None
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return path


class StoreRaceError(FileExistsError):
    """Another process created the store while this one was creating it (two new sweeps
    started on one ``--out`` at once): this one's creation is discarded."""

    def __init__(self, path):
        super().__init__(errno.EEXIST, f"{path} was created by another process while this one "
                         f"was creating it; this run stops and writes nothing. Let that run "
                         f"finish, or continue its store with --resume")

    def __str__(self) -> str:
        return self.strerror


def clean_interrupted_creations(path) -> list[Path]:
    """Remove the hidden folders (``.NAME.creating-HOST-PID-…``) that a store creation on
    this host left when it was killed (its process is gone); returns them."""
    path = Path(path)
    return remove_orphans(path.parent, f".{path.name}.creating",
                          "an interrupted store creation")


# --------------------------------------------------------------------------- lock

LOCK_SUFFIX = ".lock"


def lock_path(path) -> Path:
    """The lock file of the store at ``path``: ``STORE.lock`` beside it."""
    path = Path(path)
    return path.with_name(path.name + LOCK_SUFFIX)


class StoreLockedError(RuntimeError):
    """Another live process is writing the store (``holder``: its host, PID, start)."""

    def __init__(self, path, holder: dict):
        self.holder = holder
        super().__init__(
            f"{path} is being written by another process: host {holder.get('host')}, PID "
            f"{holder.get('pid')}, since {holder.get('started_utc')}. Wait for it to finish; if "
            f"that process is gone (another host cannot be checked from here), delete "
            f"{lock_path(path)} and resume.")


class StoreLock:
    """An exclusive writer's lock on a store: the file ``STORE.lock`` beside it (inside, Zarr
    would list it as a stray node) holding the host, PID and start time of its holder,
    created atomically (O_EXCL). A lock whose holder ran on this host and is no longer alive
    is stale: it is taken over (``recovered`` names it). Use as a context manager."""

    def __init__(self, path):
        self.file = lock_path(path)
        self.path = Path(path)
        self.recovered: dict | None = None
        self.record = {"host": socket.gethostname(), "pid": os.getpid(), "started_utc": utc_now()}

    def acquire(self) -> StoreLock:
        for _ in range(2):
            try:
                fd = os.open(self.file, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                holder = self._holder()
                if (holder.get("host") == self.record["host"]
                        and isinstance(holder.get("pid"), int)
                        and not pid_alive(holder["pid"])):
                    self.recovered = holder  # stale: its process died (SIGKILL, power)
                    self.file.unlink(missing_ok=True)
                    continue
                raise StoreLockedError(self.path, holder) from None
            with os.fdopen(fd, "w") as f:
                json.dump(self.record, f)
            register_emergency_cleanup(id(self), self.release)  # also on an immediate exit
            return self
        raise StoreLockedError(self.path, self._holder())

    def _holder(self) -> dict:
        try:
            return json.loads(self.file.read_text())
        except (OSError, ValueError):
            return {"host": "?", "pid": "?", "started_utc": "? (unreadable lock file)"}

    def release(self) -> None:
        unregister_emergency_cleanup(id(self))
        if self._holder().get("pid") == self.record["pid"]:
            self.file.unlink(missing_ok=True)

    def __enter__(self) -> StoreLock:
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


def _open_group(path, mode: str = "r"):
    import zarr

    # the arrays' own metadata, not .zmetadata: a damaged consolidated copy must not hide
    # an intact store (it is rewritten when a run ends, record_run)
    return zarr.open_group(str(path), mode=mode, zarr_format=ZARR_FORMAT, use_consolidated=False)


def _one_line(err: BaseException, limit: int = 120) -> str:
    return f"{type(err).__name__}: {' '.join(str(err).split())[:limit]}"


def is_store(path) -> bool:
    """Whether ``path`` is a folder whose attributes say it is an lfjax sweep store."""
    path = Path(path)
    if not path.is_dir():
        return False
    try:
        return _open_group(path).attrs.get("format") == STORE_FORMAT
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
                return f"its metadata file {name} is damaged ({_one_line(err)})"
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
        return f".zmetadata (the consolidated metadata) is damaged ({_one_line(err)})"
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
        group = _open_group(path)
        stored = group.attrs.get("metadata_checksum")
        if stored is None:
            return None
        if metadata_checksum(group) != int(stored):
            return ("its configuration or coordinates do not match the checksum written with "
                    "them (attribute metadata_checksum): an attribute or a coordinate file was "
                    "altered")
    except Exception as err:  # noqa: BLE001 - any failure to read them is damage
        return f"its configuration or coordinates cannot be read ({_one_line(err)})"
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
    attrs = _open_group(path).attrs
    # keys added since the store was written are at their defaults there (with_new_defaults)
    stored = {"config": with_new_defaults(json.loads(attrs["config_json"])),
              "lfjax_version": attrs["lfjax_version"]}
    current = json.loads(json.dumps(_stored_record(config), sort_keys=True))
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
            broken[i] = f"bookkeeping file {name}/{i} is unreadable ({_one_line(err, 80)})"
    return values, broken


def read_bookkeeping(path) -> Bookkeeping:
    """The store's :class:`Bookkeeping` (``chunk_complete`` and ``chunk_checksum``): a
    damaged or missing mark file is named, not raised. Marks are written complete first,
    checksum second, and unmarked in the same order: a chunk marked complete without a
    checksum, or with a checksum but not complete, has lost a bookkeeping file."""
    group = _open_group(path)
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


def chunk_dataset(config: SweepConfig, tasks: list[Task], results: dict, start: int, stop: int):
    """The store's eye-dimensioned variables for eyes ``start:stop`` from each task's
    chunk results (``results[task.key]``: :meth:`ChunkEvaluator.evaluate`)."""
    import xarray as xr

    n = stop - start
    n_pupil, n_layout = len(config.pupil_diameters_mm), len(config.layouts)
    depths = config.depths_D
    acc = config.accommodation_D
    base = (n, n_pupil, n_layout, depths.size)
    m = len(METRICS)
    arrays = {
        "vsotf": np.full(base + (acc.size,), np.nan, np.float32),
        "strehl": np.full(base + (acc.size,), np.nan, np.float32),
        "predicted_accommodation": np.full(base + (m,), np.nan),
        "predicted_accommodation_continuous": np.full(base + (m,), np.nan),
        "continuous_peak_success": np.zeros(base + (m,), bool),
        "peak_value": np.full(base + (m,), np.nan, np.float32),
        "cutoff_frequency": np.full(base + (m,), np.nan, np.float32),
        "mtf_at_peak": np.full(base + (m, FREQUENCIES_CPD.size), np.nan, np.float32),
    }
    for task in tasks:
        r = results[task.key]
        pi, li, slots = task.pupil_index, task.layout_index, list(task.depth_slots)
        # grid states are the shared absolute grid: index k of the window is acc[k]
        arrays["vsotf"][:, pi, li, slots] = r["vsotf"]
        arrays["strehl"][:, pi, li, slots] = r["strehl"]
        arrays["predicted_accommodation"][:, pi, li, slots] = acc[r["grid_index"]]
        arrays["predicted_accommodation_continuous"][:, pi, li, slots] = r["continuous"]
        arrays["continuous_peak_success"][:, pi, li, slots] = r["continuous_success"]
        arrays["peak_value"][:, pi, li, slots] = r["peak_value"]
        arrays["cutoff_frequency"][:, pi, li, slots] = r["cutoff_frequency"]
        arrays["mtf_at_peak"][:, pi, li, slots] = r["mtf_at_peak"]
    depth_b = depths[None, None, None, :, None]
    arrays["accommodation_error"] = arrays["predicted_accommodation"] - depth_b
    arrays["continuous_error"] = arrays["predicted_accommodation_continuous"] - depth_b
    dims = {
        "vsotf": ("eye", "pupil", "layout", "depth", "accommodation"),
        "strehl": ("eye", "pupil", "layout", "depth", "accommodation"),
        "mtf_at_peak": ("eye", "pupil", "layout", "depth", "metric", "frequency"),
    }
    return xr.Dataset({name: (dims.get(name, ("eye", "pupil", "layout", "depth", "metric")), a)
                       for name, a in arrays.items()})


def chunk_checksum(part, zernike_um=None) -> int:
    """BLAKE2b-64 of a chunk's eye variables (name, dtype, shape and values; every NaN
    counted alike) and, when given (checksum scheme 2, :data:`CHECKSUM_SCHEME`), its eyes'
    ``zernike_um`` (n, n_modes) µm, as an unsigned 64-bit integer; never 0."""
    h = hashlib.blake2b(digest_size=8)
    arrays = [(name, np.asarray(part[name].values)) for name in sorted(_EYE_VARIABLES)]
    if zernike_um is not None:
        arrays.append(("zernike_um", np.asarray(zernike_um, np.float64)))
    for name, a in arrays:
        if a.dtype.kind == "f":
            a = np.where(np.isnan(a), np.nan, a).astype(a.dtype)
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(np.ascontiguousarray(a).tobytes())
    return int.from_bytes(h.digest(), "little") or 1


def write_chunk(path, chunk_index: int, part, start: int, stop: int, zernike_um=None) -> None:
    """Write one chunk's variables into its region (and, given, its eyes' ``zernike_um``:
    rewritten, so a recomputed chunk repairs them too), then mark the chunk complete with
    the checksum of what was written."""
    import xarray as xr

    part.to_zarr(str(path), region={"eye": slice(start, stop)}, mode="r+", consolidated=False,
                 zarr_format=ZARR_FORMAT)
    if zernike_um is not None:
        _open_group(path, "r+")["zernike_um"][start:stop] = np.asarray(zernike_um, float)
        # the checksum of the coefficients as stored (float64 both ways: the same bits)
    xr.Dataset({"chunk_complete": (("chunk",), np.ones(1, bool)),
                "chunk_checksum": (("chunk",), np.array([chunk_checksum(part, zernike_um)],
                                                        np.uint64))}
               ).to_zarr(str(path), region={"chunk": slice(chunk_index, chunk_index + 1)},
                         mode="r+", consolidated=False, zarr_format=ZARR_FORMAT)


def unmark_chunks(path, chunks) -> None:
    """Mark ``chunks`` not complete (their data are to be recomputed)."""
    import zarr

    group = zarr.open_group(str(path), mode="r+", zarr_format=ZARR_FORMAT,
                            use_consolidated=False)
    for i in chunks:  # each mark is its own file: a damaged one is replaced, not read
        group["chunk_complete"][int(i)] = False
        if "chunk_checksum" in group:
            group["chunk_checksum"][int(i)] = 0


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
        attrs = _open_group(path).attrs
        size = int(attrs["chunk_size"])
        with_zernike = int(attrs.get("checksum_scheme", 1)) >= 2
        ds = xr.open_zarr(str(path), consolidated=False, zarr_format=ZARR_FORMAT)
        n_eye = ds.sizes["eye"]
    except Exception as err:  # noqa: BLE001 - report, never raise
        result.problems.append(f"its chunk bookkeeping cannot be read ({_one_line(err)})")
        return result
    names = list(_EYE_VARIABLES) + (["zernike_um"] if with_zernike else [])
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
            result.corrupt[i] = f"unreadable ({_one_line(err)})"
            continue
        zernike = part["zernike_um"].values if with_zernike else None
        if chunk_checksum(part, zernike) != int(marks.sums[i]):
            result.corrupt[i] = ("data do not match the checksum written with them (a chunk "
                                 "file missing or altered, its eyes' zernike_um among them)")
            continue
        result.ok.append(i)
    return result


def open_store(path, complete_only: bool = False):
    """The sweep's Dataset (loaded into memory). ``complete_only``: keep only the eyes of
    completed chunks (a partial sweep read while it runs, or after an interruption). A
    chunk whose marks are damaged (:func:`read_bookkeeping`) counts as not complete, with a
    warning naming it; damaged consolidated metadata are read around, with a warning."""
    import xarray as xr

    path = Path(path)
    if not is_store(path):
        raise ValueError(not_a_store(path))
    damage = consolidated_damage(path)
    if damage is not None:
        warnings.warn(f"{path}: {damage}; read from the arrays' own metadata (lfjax sweep "
                      f"--resume rewrites it)", stacklevel=2)
    marks = read_bookkeeping(path)
    if marks.damaged:
        warnings.warn(f"{path}: chunk(s) {sorted(marks.damaged)} counted as not computed: "
                      + "; ".join(marks.damaged[i] for i in sorted(marks.damaged))
                      + " (lfjax sweep CONFIG --out STORE --resume recomputes them)",
                      stacklevel=2)
    lazy = xr.open_zarr(str(path), consolidated=_has_consolidated(path) and damage is None,
                        zarr_format=ZARR_FORMAT)
    ds = lazy.drop_vars(list(BOOKKEEPING), errors="ignore").load()
    ds["chunk_complete"] = ("chunk", marks.done)
    ds["chunk_complete"].attrs.update(lazy["chunk_complete"].attrs)
    if marks.has_checksums:
        ds["chunk_checksum"] = ("chunk", marks.sums)
        ds["chunk_checksum"].attrs.update(lazy["chunk_checksum"].attrs)
    if complete_only:
        size = int(ds.attrs["chunk_size"])
        done = np.repeat(ds.chunk_complete.values, size)[: ds.sizes["eye"]]
        ds = ds.isel(eye=np.flatnonzero(done))
    return ds


def _has_consolidated(path) -> bool:
    return (Path(path) / ".zmetadata").is_file()


def is_disk_full(err: BaseException) -> bool:
    """The error (or one it was raised from) is 'no space left on device'."""
    while err is not None:
        if isinstance(err, OSError) and err.errno in (errno.ENOSPC, errno.EDQUOT):
            return True
        err = err.__cause__ or err.__context__
    return False


def study_view(ds, pupil_mm: float | None = None):
    """One pupil of a sweep store as the reproduction's study Dataset: dims ``layout, eye,
    depth, accommodation, metric, frequency``, eyes labelled ``eye00001`` … and
    ``average`` — what :func:`lfjax.vision.claims.evaluate_claims` reads."""
    if pupil_mm is None:
        if ds.sizes["pupil"] != 1:
            raise ValueError(f"the store holds pupils {ds.pupil.values.tolist()} mm: name one")
        pupil_mm = float(ds.pupil.values[0])
    if not np.any(np.isclose(ds.pupil.values, pupil_mm)):
        raise ValueError(f"pupil_mm={pupil_mm} is not in the store (pupils "
                         f"{ds.pupil.values.tolist()} mm)")
    view = ds.sel(pupil=pupil_mm, method="nearest").drop_vars(
        ["chunk_complete", "chunk_checksum"], errors="ignore")
    labels = [("average" if avg else f"eye{int(e) + 1:05d}")
              for e, avg in zip(view.eye.values, view.is_average.values)]
    view = view.assign_coords(eye=("eye", labels))
    order = [d for d in ("layout", "eye", "depth", "accommodation", "metric", "frequency",
                         "zernike_j") if d in view.dims]
    view = view.transpose(*order, ...)
    view.attrs = dict(ds.attrs, pupil_diameter_mm=float(pupil_mm))
    return view


__all__ = [
    "LOCK_SUFFIX",
    "lock_path",
    "STORE_FORMAT",
    "StoreLock",
    "StoreLockedError",
    "StoreDamagedError",
    "StoreRaceError",
    "Bookkeeping",
    "CHECKSUM_SCHEME",
    "Verification",
    "metadata_checksum",
    "metadata_problem",
    "not_a_store",
    "read_bookkeeping",
    "store_damage",
    "chunk_checksum",
    "clean_interrupted_creations",
    "is_disk_full",
    "record_run",
    "unmark_chunks",
    "verify_store",
    "StoreMismatchError",
    "check_store_matches",
    "chunk_dataset",
    "completed_chunks",
    "create_store",
    "is_store",
    "open_store",
    "stored_attribute",
    "stored_samplings",
    "spectral_record",
    "stored_spectra",
    "study_view",
    "template",
    "write_chunk",
]
