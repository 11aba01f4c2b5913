"""A sweep's results on disk: one labelled xarray Dataset in a Zarr store, written by chunks.

The store is created whole before any compute (NaN where nothing is computed yet; empty
Zarr chunks take no space), in a temporary folder renamed into place, so a store either
exists with its full metadata or not at all. Each chunk of eyes is then written into its
own region of the ``eye`` axis — the Zarr chunking along ``eye`` equals the compute chunk,
so no two writers (processes) ever touch the same file — and only after its data is written
is the chunk marked in ``chunk_complete``, with the checksum of what was written in
``chunk_checksum``. A chunk interrupted half-way is therefore unmarked and recomputed on
resume; a finished one is recomputed only when its data no longer match its checksum
(:func:`~lfjax.sweep.store_checks.verify_store`). One writer at a time holds
:class:`~lfjax.sweep.store_lock.StoreLock` (``STORE.lock``). The metadata are consolidated,
and the attributes record the provenance (:func:`lfjax._version.stamp`).

This module writes and reads the store (its layout, :func:`template`, the chunks);
:mod:`lfjax.sweep.store_checks` recognises a store and checks its integrity and its
configuration; :mod:`lfjax.sweep.store_lock` is the one writer's lock.

Dataset (dims ``eye, pupil, layout, depth, accommodation, metric, frequency, zernike_j,
chunk``), see :func:`template` for every variable's units. :func:`study_view` presents one
pupil of a store as the reproduction's study Dataset, so the paper's claims
(:func:`lfjax.vision.claims.evaluate_claims`) run on any subset of its eyes.
"""

from __future__ import annotations

import dataclasses
import errno
import json
import os
import shutil
import socket
import warnings
from pathlib import Path

import numpy as np

from lfjax.base.files import owned_temp_dir, remove_orphans
from lfjax._version import stamp, utc_now
from lfjax.vision.peak_options import METRICS
from lfjax.base.sampling import Sampling
from lfjax.model.spectral import make_spectrum
from lfjax.sweep.compute import (FREQUENCIES_CPD, Task, layout_name, spectral_plans,
                                 sweep_spectra)
from lfjax.sweep.config import SweepConfig
from lfjax.sweep.config_files import config_to_toml
from lfjax.sweep.store_checks import (
    BOOKKEEPING,
    CHECKSUM_SCHEME,
    EYE_VARIABLES,
    STORE_FORMAT,
    ZARR_FORMAT,
    StoreCorruptError,
    Verification,
    chunk_checksum,
    chunk_mismatch,
    consolidated_damage,
    is_store,
    metadata_checksum,
    metadata_problem,
    not_a_store,
    one_line,
    open_group,
    read_bookkeeping,
    stored_record,
    verify_store,
)


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

    spectra = spectral_record(config, tasks)
    plan = _task_arrays(config, tasks, spectra)
    data_vars = _result_variables(config, int(np.shape(zernike_um)[0]))
    data_vars.update(_setup_variables(config, zernike_um, plan))
    return xr.Dataset(data_vars=data_vars,
                      coords=_coordinates(config, zernike_um, is_average, plan),
                      attrs=_store_attrs(config, spectra, plan["samplings"]))


def _task_arrays(config: SweepConfig, tasks: list[Task], spectra: dict) -> dict:
    """Each (pupil, layout)'s plan as arrays (pupil, layout): ``steps`` (frequency step,
    cpd), ``n_fft``, ``n_sub`` (subapertures), ``sub_diam`` (mm), ``n_wl`` (wavelengths),
    and ``samplings`` ({"pupil_index,layout_index": Sampling as a dict})."""
    n_pupil, n_layout = len(config.pupil_diameters_mm), len(config.layouts)
    steps = np.full((n_pupil, n_layout), np.nan)
    n_fft = np.zeros((n_pupil, n_layout), np.int32)
    n_sub = np.zeros((n_pupil, n_layout), np.int32)
    sub_diam = np.full((n_pupil, n_layout), np.nan)
    samplings = {}
    n_wl = np.zeros((n_pupil, n_layout), np.int32)
    for t in tasks:
        n_wl[t.key] = spectra[f"{t.pupil_index},{t.layout_index}"]["n_wavelengths"]
        steps[t.key] = t.sampling.freq_step_cpd
        n_fft[t.key] = t.pipeline_config.n_fft
        n_sub[t.key] = t.layout.n_subapertures
        sub_diam[t.key] = float(np.max(np.asarray(t.layout.diameters_mm)))
        samplings[f"{t.pupil_index},{t.layout_index}"] = dataclasses.asdict(t.sampling)
    return dict(steps=steps, n_fft=n_fft, n_sub=n_sub, sub_diam=sub_diam, n_wl=n_wl,
                samplings=samplings)


def _store_attrs(config: SweepConfig, spectra: dict, samplings: dict) -> dict:
    """The store's attributes: its format, the configuration it was made by (what a resume
    is checked against), the units, the spectra and samplings planned, and its provenance
    (:func:`lfjax._version.stamp`)."""
    record = stored_record(config)
    made = stamp()  # who made the store (provenance_json); the version also heads the attrs
    return {
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


def _result_variables(config: SweepConfig, n_eye: int) -> dict:
    """The eye variables (NaN until their chunk is written): {name: (dims, values, attrs)}."""
    n_pupil, n_layout = len(config.pupil_diameters_mm), len(config.layouts)
    acc = config.accommodation_D
    base = (n_eye, n_pupil, n_layout, config.depths_D.size)
    dims5 = ("eye", "pupil", "layout", "depth")
    nan = lambda shape, dtype=np.float32: np.full(shape, np.nan, dtype)  # noqa: E731
    per_metric = base + (len(METRICS),)
    metric_note = "metric axis: vsotf, strehl"
    return dict(
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
    )


def _setup_variables(config: SweepConfig, zernike_um, plan: dict) -> dict:
    """The eyes' coefficients, each (pupil, layout)'s plan and the chunk bookkeeping:
    {name: (dims, values, attrs)}."""
    return dict(
        zernike_um=(("eye", "zernike_j"), np.asarray(zernike_um, float), {
            "long_name": "OSA/ANSI Zernike coefficients on the measured pupil "
                         "(piston and tilt zeroed)", "units": "um"}),
        freq_step_cpd=(("pupil", "layout"), plan["steps"], {
            "long_name": "frequency step of the OTF grid (PSF field 60/df arcmin)",
            "units": "cpd"}),
        n_fft=(("pupil", "layout"), plan["n_fft"], {"long_name": "FFT size of the OTF grid"}),
        n_wavelengths=(("pupil", "layout"), plan["n_wl"], {
            "long_name": "wavelengths summed (the rule, its nodes and weights: attribute "
                         "spectra_json)"}),
        chunk_complete=(("chunk",), np.zeros(config.n_chunks, bool), {
            "long_name": "the chunk's eyes are written (eyes chunk*chunk_size …)"}),
        chunk_checksum=(("chunk",), np.zeros(config.n_chunks, np.uint64), {
            "long_name": "BLAKE2b-64 of the chunk's eye variables and its eyes' "
                         "zernike_um as written (lfjax.sweep.store_checks.chunk_checksum; 0: not "
                         "written); the configuration and the other arrays: attribute "
                         "metadata_checksum"}),
    )


def _coordinates(config: SweepConfig, zernike_um, is_average, plan: dict) -> dict:
    """The store's coordinates: {name: (dims, values[, attrs])}."""
    n_eye = int(np.shape(zernike_um)[0])
    depths = config.depths_D
    acc = config.accommodation_D
    return dict(
        eye=("eye", np.arange(n_eye)),
        is_average=("eye", np.asarray(is_average, bool),
                    {"long_name": "the Thibos et al. (2002) average eye"}),
        pupil=("pupil", np.asarray(config.pupil_diameters_mm, float),
               {"long_name": "calculation pupil diameter", "units": "mm"}),
        layout=("layout", [layout_name(e) for e in config.layouts]),
        layout_entry=("layout", list(config.layouts)),
        n_subapertures=(("pupil", "layout"), plan["n_sub"]),
        subaperture_diameter_mm=(("pupil", "layout"), plan["sub_diam"], {"units": "mm"}),
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
    )


def record_run(path, started_utc: str, computed: list[int]) -> None:
    """Append this run (host, PID, start and end, chunks computed) to the store's
    ``runs_json`` attribute, mark ``completed_utc`` once every chunk is written, and
    re-consolidate the metadata. Process 0 only (attributes are one file)."""
    import zarr

    group = open_group(path, "r+")
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
    return open_group(path).attrs.get(name, default)


def stored_samplings(path) -> dict:
    """{(pupil_index, layout_index): Sampling} recorded in a store."""
    attrs = open_group(path).attrs
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
    attrs = open_group(path).attrs
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


def write_chunk(path, chunk_index: int, part, start: int, stop: int, zernike_um=None) -> None:
    """Write one chunk's variables into its region (and, given, its eyes' ``zernike_um``:
    rewritten, so a recomputed chunk repairs them too), then mark the chunk complete with
    the checksum of what was written."""
    import xarray as xr

    part.to_zarr(str(path), region={"eye": slice(start, stop)}, mode="r+", consolidated=False,
                 zarr_format=ZARR_FORMAT)
    if zernike_um is not None:
        open_group(path, "r+")["zernike_um"][start:stop] = np.asarray(zernike_um, float)
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


def open_store(path, complete_only: bool = False):
    """The sweep's Dataset (loaded into memory). ``complete_only``: keep only the eyes of
    completed chunks (a partial sweep read while it runs, or after an interruption). A
    chunk whose marks are damaged (:func:`~lfjax.sweep.store_checks.read_bookkeeping`)
    counts as not complete, with a warning naming it; damaged consolidated metadata are
    read around, with a warning."""
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


def open_verified_store(path, complete_only: bool = True):
    """:func:`open_store` of a store that ``lfjax sweep --verify`` passes, or a
    :class:`~lfjax.sweep.store_checks.StoreCorruptError` naming every damage
    (:func:`~lfjax.sweep.store_checks.verify_store`'s checks: the configuration and
    coordinates against ``metadata_checksum``, the consolidated metadata, the chunk marks,
    and each complete chunk's data against its checksum; a chunk without a checksum, from a
    store older than checksums, is read unchecked as there).

    The store is read once: the eyes of complete chunks (all of them unless
    ``complete_only``: the rest are not checked) are loaded, then each complete chunk is
    hashed in memory (BLAKE2b of its eye variables, a fraction of the read's time), and
    ``metadata_checksum`` re-reads only the arrays without an ``eye`` axis. Only when the
    load fails (a file that does not decode) is the store read chunk by chunk
    (:func:`~lfjax.sweep.store_checks.verify_store`) to name the chunks."""
    import xarray as xr

    path = Path(path)
    if not is_store(path):
        raise ValueError(not_a_store(path))
    found = Verification([], {}, [], [])
    found.problems += [why for why in (consolidated_damage(path), metadata_problem(path))
                       if why is not None]
    marks = read_bookkeeping(path)
    found.corrupt.update(marks.damaged)
    lazy = xr.open_zarr(str(path), consolidated=False, zarr_format=ZARR_FORMAT)
    size, n_eye = int(lazy.attrs["chunk_size"]), lazy.sizes["eye"]
    done = np.repeat(marks.done, size)[:n_eye]
    try:
        ds = lazy.drop_vars(list(BOOKKEEPING), errors="ignore")
        ds = (ds.isel(eye=np.flatnonzero(done)) if complete_only else ds).load()
    except Exception as err:  # noqa: BLE001 - a file that does not decode: find which
        checked = verify_store(path)
        if checked.healthy:  # not in a complete chunk's data
            checked.problems.append(f"its data cannot be read ({one_line(err)})")
        raise StoreCorruptError(path, checked) from None
    with_zernike = int(lazy.attrs.get("checksum_scheme", 1)) >= 2
    names = list(EYE_VARIABLES) + (["zernike_um"] if with_zernike else [])
    for i in np.flatnonzero(marks.done & (marks.sums != 0)):
        first, last = i * size, min((i + 1) * size, n_eye)
        start = int(done[:first].sum()) if complete_only else first  # its place in ds
        why = chunk_mismatch(ds[names].isel(eye=slice(start, start + last - first)),
                             int(marks.sums[i]), with_zernike)
        if why is not None:
            found.corrupt[int(i)] = why
    if not found.healthy:
        raise StoreCorruptError(path, found)
    ds["chunk_complete"] = ("chunk", marks.done)
    ds["chunk_complete"].attrs.update(lazy["chunk_complete"].attrs)
    if marks.has_checksums:
        ds["chunk_checksum"] = ("chunk", marks.sums)
        ds["chunk_checksum"].attrs.update(lazy["chunk_checksum"].attrs)
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
    "chunk_dataset",
    "clean_interrupted_creations",
    "create_store",
    "is_disk_full",
    "open_store",
    "open_verified_store",
    "record_run",
    "spectral_record",
    "stored_attribute",
    "stored_samplings",
    "stored_spectra",
    "StoreRaceError",
    "study_view",
    "template",
    "unmark_chunks",
    "write_chunk",
]
