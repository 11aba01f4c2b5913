"""`lfjax sweep-report` and "what ten eyes cannot tell" (lfjax.sweep.report, .ten_eyes).

One tiny real sweep (12 eyes + the average eye, natural / 2x2 / 3x3, three depths, two
wavelengths) is computed once for the module. Its chunk size is 7, so
the store has two chunks and one can be marked incomplete on a copy.

Covers: lfjax.sweep.ten_eyes, lfjax.cli.sweep_report, lfjax.base.tables
"""

from __future__ import annotations

import shutil
import types

import numpy as np
import pandas as pd
import pytest

from lfjax import cli
from lfjax.vision.claim_core import StudyNumbers
from lfjax.vision.claims import evaluate_claims
from lfjax.sweep import config_from_dict, open_store, run_sweep, study_view
from lfjax.sweep import report as sr
from lfjax.sweep import ten_eyes as te

N_EYES = 12

TINY = {
    "population": {"n_eyes": N_EYES, "seed": 0},
    "display": {"layouts": ["natural", "2x2", "3x3"], "depth_offsets_D": [-1.0, 0.0, 1.0]},
    "accommodation": {"step_D": 0.5, "window_D": 1.0},
    # two wavelengths (each is its own FFT band of the compiled programs): a given step
    # recorded as one uniform rule is still a grid, summed with V(λ) weights
    "spectrum": {"wavelengths_nm": [500.0, 600.0, 100.0]},
    "run": {"chunk_size": 7},
}


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    path = tmp_path_factory.mktemp("sweep") / "tiny.zarr"
    run_sweep(config_from_dict(TINY), path, progress=False)
    return path


@pytest.fixture(scope="module")
def ds(store):
    return open_store(store, complete_only=True)


@pytest.fixture(scope="module")
def report(store, tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    files = sr.sweep_report(store, out, draws=30, seed=1)
    return out, files


# ------------------------------------------------------------------ percentiles


def test_percentiles_csv_matches_numpy(ds, report):
    _, files = report
    table = pd.read_csv(files["percentiles"])
    exact = sr.percentile_table(ds)
    assert len(exact) == len(table)
    virtual = ~ds.is_average.values
    checked = 0
    for row, full in zip(table.itertuples(index=False), exact.itertuples(index=False)):
        cell = (ds[row.variable].sel(pupil=row.pupil_mm, layout=row.layout, depth=row.depth_D,
                                     metric=row.metric).values[virtual]).astype(np.float64)
        cell = cell[np.isfinite(cell)]
        assert row.n == cell.size
        expected = np.percentile(cell, sr.PERCENTILES)
        got = [getattr(full, f"p{q}") for q in sr.PERCENTILES]
        np.testing.assert_array_equal(got, expected)
        assert full.mean == cell.mean()
        # the CSV holds them to 6 significant digits
        got = [getattr(row, f"p{q}") for q in sr.PERCENTILES]
        np.testing.assert_allclose(got, expected, rtol=5e-6, atol=1e-12)
        np.testing.assert_allclose(row.mean, cell.mean(), rtol=5e-6, atol=1e-12)
        checked += 1
    # natural view: the CDP only (no rows for its NaN cells); LF layouts: every depth;
    # grid and continuous VSOTF error, grid Strehl error, cut-off, peak value (no
    # continuous Strehl: not refined in this sweep)
    assert checked == (1 + 2 * 3) * 5
    assert not table[["p5", "p50", "p95", "mean"]].isna().any().any()
    natural = table[table.layout == "natural"]
    assert set(natural.depth_rel_cdp_D) == {0.0}
    assert set(table.n) == {N_EYES}
    assert (table.p5 <= table.p25).all() and (table.p75 <= table.p95).all()


def test_average_eye_is_excluded(ds):
    base = sr.percentile_table(ds)
    # make the average eye absurd: no population statistic may move
    wild = ds.copy(deep=True)
    avg = np.flatnonzero(wild.is_average.values)
    for name in ("accommodation_error", "continuous_error", "cutoff_frequency", "peak_value"):
        data = wild[name].values
        data[avg] = 1e6
    pd.testing.assert_frame_equal(sr.percentile_table(wild), base)
    # and counting it in would change them
    everyone = wild.assign_coords(is_average=("eye", np.zeros(wild.sizes["eye"], bool)))
    assert (sr.percentile_table(everyone).p95 > 1e5).all()


def test_error_figure_rows_prefer_continuous(ds):
    rows = sr.error_rows(sr.percentile_table(ds))
    assert set(rows.peak) == {"continuous"}
    assert len(rows) == 1 + 2 * 3


# ------------------------------------------------------------------ report files


def test_report_writes_every_file(report):
    _, files = report
    assert set(files) == set(sr.FILES)
    for key in ("accommodation_error", "cutoff_frequency", "layouts"):
        data = files[key].read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000, key
    summary = files["summary"].read_text()
    assert f"{N_EYES} virtual eyes" in summary and "seed 0" in summary
    assert "All 2 chunks complete" in summary
    for name in ("accommodation_error.png", "cutoff_frequency.png", "layouts.png",
                 "percentiles.csv", "ten_eyes.csv"):
        assert f"({name})" in summary, name
    # sampling per layout, from the store
    for layout in ("natural", "2x2", "3x3"):
        assert f"| 3 | {layout} |" in summary
    assert "What ten eyes cannot tell" in summary and "Wilson" in summary
    ten = pd.read_csv(files["ten_eyes_csv"])
    assert list(ten.claim.astype(str)) == [str(i) for i in range(1, 8)]
    assert (ten.n_draws == 30).all() and (ten.sample_size == 10).all()
    assert "| 1 |" in files["ten_eyes_md"].read_text()


def test_summary_lists_the_display_keys_set(report, store, tmp_path, monkeypatch):
    """SUMMARY.md names the display keys a sweep set away from their defaults, with units
    (here the tiny store's config with two of them changed: the text is the config's), and
    the ideal display when none is."""
    assert "- Display: the paper's ideal display" in report[1]["summary"].read_text()
    stored = sr.stored_config

    def with_display_keys(ds, folder):
        config, entries = stored(ds, folder)
        return config.replace(leakage_weight=0.25, pixel_width_arcmin=1.5), entries

    monkeypatch.setattr(sr, "stored_config", with_display_keys)
    files = sr.sweep_report(store, tmp_path / "out", draws=5)
    assert ("- Display: pixel_width_arcmin = 1.5 arcmin (default 0); leakage_weight = 0.25 "
            "unitless (default 0) (lenticular strips") in files["summary"].read_text()


def test_incomplete_store_reports_complete_chunks_only(store, tmp_path):
    from lfjax.sweep.store import unmark_chunks

    copy = tmp_path / "partial.zarr"
    shutil.copytree(store, copy)
    unmark_chunks(copy, [0])  # eyes 0-6 no longer count (as a resume that recomputes them)
    files = sr.sweep_report(copy, tmp_path / "out", draws=5)
    summary = files["summary"].read_text()
    assert "Incomplete sweep" in summary and f"5 of {N_EYES} virtual eyes" in summary
    assert set(pd.read_csv(files["percentiles"]).n) == {5}
    # 5 eyes cannot give samples of 10: no ten-eye table, and the summary says why
    assert "ten_eyes_md" not in files and not (tmp_path / "out" / "ten_eyes.csv").exists()
    assert "Not computed" in summary and "5 complete virtual eye" in summary
    unmark_chunks(copy, [1])
    with pytest.raises(ValueError, match="no complete chunk"):
        sr.sweep_report(copy, tmp_path / "out2")


def test_several_pupils(ds, tmp_path):
    """A store of two pupils: rows for each in the CSV, a ten-eye table for each. (Made
    from the tiny sweep's numbers relabelled as a 4.5 mm pupil: the report reads the
    store, it does not check the optics. Made by hand, it has no checksums, as a store
    from before them, which the report reads unchecked as --verify does.)"""
    import xarray as xr

    other = ds.assign_coords(pupil=[4.5])
    two = xr.concat([ds, other], "pupil", data_vars="minimal", coords="minimal",
                    compat="override", join="outer").drop_vars("chunk_checksum")
    two.attrs = dict(ds.attrs, config_toml=ds.attrs["config_toml"].replace(
        "pupil_diameters_mm = [3.0]", "pupil_diameters_mm = [3.0, 4.5]"))
    for key in ("metadata_checksum", "checksum_scheme"):
        two.attrs.pop(key, None)
    path = tmp_path / "two.zarr"
    two.to_zarr(path, zarr_format=2, consolidated=False)
    files = sr.sweep_report(path, tmp_path / "out", draws=4)
    table = pd.read_csv(files["percentiles"])
    assert set(table.pupil_mm) == {3.0, 4.5}
    a, b = (table[table.pupil_mm == p].drop(columns="pupil_mm").reset_index(drop=True)
            for p in (3.0, 4.5))
    pd.testing.assert_frame_equal(a, b)
    text = files["ten_eyes_md"].read_text()
    assert "### 3 mm pupil" in text and "### 4.5 mm pupil" in text
    assert set(pd.read_csv(files["ten_eyes_csv"]).pupil_mm) == {3.0, 4.5}


def test_report_rejects_bad_input(store, tmp_path):
    with pytest.raises(ValueError, match="store_path"):
        sr.sweep_report(tmp_path, tmp_path / "out")
    with pytest.raises(ValueError, match="draws"):
        sr.sweep_report(store, tmp_path / "out", draws=0)
    (tmp_path / "file").write_text("")
    with pytest.raises(ValueError, match="out_dir"):
        sr.sweep_report(store, tmp_path / "file")


def test_stored_config_rebuilds_json_layouts(tmp_path):
    """A layout JSON named by a relative path is rebuilt from the copy the store recorded
    (the file itself may be gone, and its folder is unknown to the store)."""
    from lfjax.layout_opt import save_layout_json
    from lfjax.model.layouts import make_layout
    from lfjax.sweep.compute import resolve_layout
    from lfjax.sweep.config_files import config_to_toml

    layout = make_layout([[-0.6, 0.0], [0.6, 0.0]], [1.0, 1.2], 3.0, name="pair")
    save_layout_json(tmp_path / "pair.json", layout, 3.0)
    data = dict(TINY, display=dict(TINY["display"], layouts=["natural", "pair.json"]))
    config = config_from_dict(data, base_dir=tmp_path)
    fake = types.SimpleNamespace(attrs={"config_toml": config_to_toml(config),
                                        "config_json": config.to_json()})
    (tmp_path / "pair.json").unlink()
    folder = tmp_path / "rebuilt"
    folder.mkdir()
    rebuilt, entries = sr.stored_config(fake, folder)
    got = resolve_layout(rebuilt, entries["pair.json"], 3.0)
    np.testing.assert_allclose(np.asarray(got.centres_mm), np.asarray(layout.centres_mm))
    np.testing.assert_allclose(np.asarray(got.diameters_mm), np.asarray(layout.diameters_mm))
    assert entries["natural"] == "natural"


# ------------------------------------------------------------------ ten eyes


def test_ten_eye_fractions_match_a_direct_loop(ds):
    result = te.ten_eye_claims(ds, n_draws=12, sample_size=10, seed=3)
    view = study_view(ds)
    virtual = np.flatnonzero(~view.is_average.values)
    average = np.flatnonzero(view.is_average.values)
    rng = np.random.default_rng(3)
    verdicts = []
    for i in range(12):
        pick = np.sort(rng.choice(virtual.size, size=10, replace=False))
        assert list(result.sample_eye.values[i]) == list(view.eye.values[virtual[pick]])
        claims = evaluate_claims(view.isel(eye=np.r_[virtual[pick], average]))
        verdicts.append([{True: 1, False: 0, None: -1}[c.holds] for c in claims])
    verdicts = np.asarray(verdicts)
    np.testing.assert_array_equal(result.verdict.values, verdicts)
    holds = (verdicts == 1).sum(0)
    evaluated = (verdicts >= 0).sum(0)
    np.testing.assert_array_equal(result.n_holds.values, holds)
    np.testing.assert_array_equal(result.n_na.values, (verdicts == -1).sum(0))
    with np.errstate(invalid="ignore", divide="ignore"):
        np.testing.assert_allclose(result.fraction_holds.values, holds / evaluated)
    population = evaluate_claims(view)
    assert list(result.population_verdict.values) == [c.verdict for c in population]
    # same seed, same samples and verdicts
    again = te.ten_eye_claims(ds, n_draws=12, sample_size=10, seed=3)
    np.testing.assert_array_equal(again.verdict.values, result.verdict.values)
    np.testing.assert_array_equal(again.sample_eye.values, result.sample_eye.values)


def test_sample_numbers_give_the_datasets_own_results(ds):
    """A sample taken from the population's numbers (StudyNumbers.take_eyes, what the
    draws judge) gives the claims of the Dataset's own selection of those eyes, every
    number of every result string included."""
    view = study_view(ds)
    numbers = StudyNumbers.from_dataset(te.claims_view(ds))
    average = int(np.flatnonzero(view.is_average.values)[0])
    rng = np.random.default_rng(7)
    for size in (2, 5, 10, N_EYES):
        rows = np.r_[np.sort(rng.choice(N_EYES, size=size, replace=False)), average]
        fast = evaluate_claims(numbers.take_eyes(rows))
        slow = evaluate_claims(view.isel(eye=rows))
        assert [(c.id, c.holds, c.result) for c in fast] == \
               [(c.id, c.holds, c.result) for c in slow]


def test_wilson_interval():
    z2 = te.Z_95 ** 2
    low, high = te.wilson_interval([0, 10, 5], [10, 10, 10])
    np.testing.assert_allclose(high[0], z2 / (10 + z2))   # 0 of n: [0, z²/(n + z²)]
    np.testing.assert_allclose(low[1], 10 / (10 + z2))
    np.testing.assert_allclose(low[2] + high[2], 1.0)     # symmetric about 1/2
    assert low[0] == 0.0 and high[1] == 1.0  # exactly: tables print 0, not 2.8e-17
    assert np.isnan(te.wilson_interval(0, 0)[0])
    with pytest.raises(ValueError, match="successes"):
        te.wilson_interval(3, 2)


def test_interval_brackets_the_fraction_and_shrinks(ds):
    few = te.ten_eye_claims(ds, n_draws=20, seed=0)
    # 12 eyes hold only C(12, 10) = 66 distinct samples of ten: 200 draws repeat them
    with pytest.warns(UserWarning, match="only 66 distinct samples of 10 exist among 12 eyes"):
        many = te.ten_eye_claims(ds, n_draws=200, seed=0)
    assert many.attrs["n_possible_samples"] == 66 and many.attrs["n_distinct_samples"] <= 66
    # a claim the samples cannot decide (claim 3: no 2x2 depth beyond +-1 D here) has no
    # fraction and no interval
    judged = (few.n_holds + few.n_fails).values > 0
    assert judged.sum() >= 5
    for r in (few, many):
        np.testing.assert_array_equal((r.n_holds + r.n_fails).values > 0, judged)
        assert np.all(np.isnan(r.fraction_holds.values[~judged]))
        assert np.all(np.isnan(r.ci_low.values[~judged]) & np.isnan(r.ci_high.values[~judged]))
        low, frac, high = (r[k].values[judged] for k in ("ci_low", "fraction_holds", "ci_high"))
        assert np.all(low <= frac) and np.all(frac <= high)
        assert np.all((0 <= low) & (high <= 1))
    # Wilson widths: <= 0.137 at n = 200 for any fraction, >= 0.161 at n = 20
    def width(r):
        return (r.ci_high.values - r.ci_low.values)[judged]

    assert np.all(width(many) < width(few))


def test_ten_eye_markdown(ds):
    from lfjax.vision.claim_core import Claim

    result = te.ten_eye_claims(ds, n_draws=10, seed=0)
    mine = [Claim(str(i), "f", "c", "r", i % 2 == 0) for i in range(1, 8)]
    text = te.ten_eye_markdown(result, this_run=mine, heading="### x")
    lines = text.splitlines()
    assert lines[0] == "### x"
    rows = [line for line in lines if line.startswith("| ") and line[2].isdigit()]
    assert len(rows) == 7
    assert rows[0].endswith("| fails |") and rows[1].endswith("| holds |")
    assert f"all {N_EYES} eyes" in text and "Wilson" in text
    table = te.ten_eye_table(result)
    assert len(table) == 7 and (table.n_holds + table.n_fails + table.n_na == 10).all()


def test_ten_eye_bad_input(ds, store):
    with pytest.raises(ValueError, match="n_draws"):
        te.ten_eye_claims(ds, n_draws=0)
    with pytest.raises(ValueError, match="sample_size"):
        te.ten_eye_claims(ds, sample_size=N_EYES + 1)
    with pytest.raises(ValueError, match="sample_size"):
        te.ten_eye_claims(ds, sample_size=0)
    with pytest.raises(ValueError, match="average eye"):
        te.ten_eye_claims(ds.isel(eye=np.flatnonzero(~ds.is_average.values)))
    with pytest.raises(ValueError, match="pupil_mm"):
        te.ten_eye_claims(ds, pupil_mm=4.5)
    with pytest.raises(ValueError, match="not an lfjax sweep store"):
        te.ten_eye_claims(store.parent)
    # a store read without complete_only while a chunk is unwritten
    holed = ds.copy(deep=True)
    holed.predicted_accommodation.values[0] = np.nan
    with pytest.raises(ValueError, match="complete_only"):
        te.ten_eye_claims(holed)
    # a path works and counts complete chunks only
    assert te.ten_eye_claims(store, n_draws=2).attrs["n_population"] == N_EYES
    with pytest.raises(ValueError, match="sample_size"):
        te.check_population_store(store, sample_size=N_EYES + 1)
    assert te.check_population_store(store, 10, prefer_pupil_mm=2.0) == 3.0


# ------------------------------------------------------------------ command line


def test_cli_sweep_report(store, tmp_path, capsys):
    out = tmp_path / "rep"
    code = cli.main(["sweep-report", str(store), "--out", str(out), "--draws", "5",
                     "--no-progress"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert str(out) in captured.out
    assert set(sr.FILES.values()) <= {p.name for p in out.iterdir()}
    assert "5 samples of 10 eyes" in (out / "ten_eyes.md").read_text()
    assert cli.main(["sweep-report", str(tmp_path / "nothing")]) == 2
    assert "not an lfjax sweep store" in capsys.readouterr().err
    assert cli.main(["sweep-report", str(store), "--draws", "0"]) == 2
    assert sr.default_out_dir(store).name == "tiny-report"


# ------------------------------------------------------------------ reproduce --population


def test_reproduce_population_section(store, ds, tmp_path, monkeypatch):
    """reproduce(population_store=...) adds the section and ten_eyes.csv. The study itself
    is replaced by the sweep's own study view (the quick study takes minutes); everything
    after it — claims, tables, the section, REPORT.md — runs as in ``lfjax reproduce``."""
    import xarray as xr

    from lfjax.reproduce import run as rep  # where reproduce looks its parts up

    view = study_view(ds)
    study = view.drop_vars(["vsotf", "strehl"]).assign(
        compute_seconds=("layout", np.zeros(view.sizes["layout"])))
    monkeypatch.setattr(rep, "run_study", lambda config, stage=None: study)
    monkeypatch.setattr(rep, "compute_examples", lambda ds, config, stage=None: xr.Dataset())
    monkeypatch.setattr(rep, "save_figures", lambda *args, **kwargs: [])
    monkeypatch.setattr(rep, "prediction_table", lambda ds: pd.DataFrame({"x": [0]}))
    config = rep.StudyConfig.quick(n_eyes=10)
    result = rep.reproduce(tmp_path / "out", config, progress=False, population_store=store,
                           population_draws=15)
    text = (result["out"] / "REPORT.md").read_text()
    assert "## What ten eyes cannot tell" in text
    section = text.split("## What ten eyes cannot tell")[1].split("\n## ")[0]
    assert "15 samples of 10 eyes" in section and "| this run |" in section
    assert rep.POPULATION_TABLE in result["files"]
    table = pd.read_csv(result["out"] / rep.POPULATION_TABLE)
    assert len(table) == 7 and (table.n_draws == 15).all()
    # the section's last column is the run's own verdicts
    for claim in result["claims"]:
        row = next(line for line in section.splitlines() if line.startswith(f"| {claim.id} |"))
        assert row.endswith(f"| {claim.verdict} |")
    # without a store: no section
    plain = rep.reproduce(tmp_path / "plain", config, progress=False)
    assert "What ten eyes" not in (plain["out"] / "REPORT.md").read_text()


def test_reproduce_population_checked_before_any_work(store, tmp_path, capsys, monkeypatch):
    from lfjax.reproduce import run as rep  # where reproduce looks its parts up

    def no_study(*args, **kwargs):
        raise AssertionError("the study ran before the population store was checked")

    monkeypatch.setattr(rep, "run_study", no_study)
    out = tmp_path / "out"
    code = cli.main(["reproduce", "--quick", "--out", str(out), "--population",
                     str(tmp_path), "--no-progress"])
    assert code == 2 and "--population" in capsys.readouterr().err
    assert not out.exists()
    with pytest.raises(ValueError, match="sample_size"):
        rep.reproduce(out, rep.StudyConfig.quick(n_eyes=N_EYES + 1), progress=False,
                      population_store=store)


def test_claims_the_data_cannot_judge_are_na(ds):
    """Claim 2 is "for every density" and claim 3's exception is about 2x2 beyond +-1 D: a
    store without 4x4, or without such depths, cannot confirm them (n/a), though data that
    refute them still make them fail."""
    from lfjax.vision.claims import evaluate_claims
    from lfjax.sweep import study_view

    view = study_view(ds)
    assert "4x4" not in view.layout.values and np.abs(view.depth_rel_cdp.values).max() <= 1.0
    # data on which both claims would hold if 2x2 and 3x3 were all there is
    grid = view.predicted_accommodation
    agreeing = grid.where(grid.metric != "strehl", grid.sel(metric="vsotf"))
    small = view.predicted_accommodation_continuous.where(
        view.metric != "vsotf", view.depth - 0.05)
    good = view.assign(predicted_accommodation=agreeing,
                       predicted_accommodation_continuous=small,
                       continuous_peak_success=view.continuous_peak_success | True)
    claims = {c.id: c for c in evaluate_claims(good)}
    assert claims["2"].verdict == "n/a" and "no 4x4 in the data" in claims["2"].result
    assert claims["3"].verdict == "n/a"
    assert "no 2x2 depth beyond +-1 D" in claims["3"].result
    # refuted by the data present: fails, whatever is missing
    far = view.assign(predicted_accommodation_continuous=small + 0.5 * (view.layout == "3x3"))
    assert {c.id: c for c in evaluate_claims(far)}["2"].verdict == "fails"


def _texts_outside(fig) -> list[str]:
    """Titles and axis labels of ``fig`` that reach beyond the figure (clipped when saved)."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    box = fig.bbox
    texts = [t for ax in fig.axes for t in (ax.title, ax.xaxis.label, ax.yaxis.label)]
    texts += [t for t in (fig._suptitle, fig._supylabel) if t is not None]
    outside = []
    for text in texts:
        if not text.get_text():
            continue
        e = text.get_window_extent(renderer)
        if e.x0 < box.x0 - 0.5 or e.x1 > box.x1 + 0.5 or e.y0 < box.y0 - 0.5 or e.y1 > box.y1 + 0.5:
            outside.append(f"{text.get_text()!r} at {tuple(round(v) for v in e.extents)}")
    return outside


def test_report_figures_keep_their_titles_and_labels_inside(ds):
    from lfjax.model.layouts import paper_layouts

    table = sr.percentile_table(ds)
    layouts = {(p, n): paper_layouts(p)[n] for p in (3.0, 6.0)
               for n in ("natural", "2x2", "3x3", "4x4")}
    for fig in (sr.fig_accommodation_error(table), sr.fig_cutoff_frequency(table, 0.05),
                sr.fig_layouts(layouts, [3.0, 6.0]),
                sr.fig_layouts({k: v for k, v in layouts.items() if k[0] == 3.0}, [3.0])):
        assert not _texts_outside(fig), _texts_outside(fig)


def test_tables_print_zero_not_roundoff():
    from lfjax.base.tables import printable

    table = pd.DataFrame({"p50": [2.2 - 2.0 - 0.2, 0.25, np.nan], "n": [1, 2, 3],
                          "layout": ["a", "b", "c"]})
    assert table.p50[0] != 0.0  # 2.8e-17: what a grid difference leaves
    text = printable(table).to_csv(index=False, float_format="%.6g")
    assert text.splitlines()[1] == "0,1,a" and "e-17" not in text
    assert np.isnan(printable(table).p50[2]) and printable(table).p50[1] == 0.25


# ------------------------------------------------------------------ spectral rules


def test_given_step_is_recorded_as_a_uniform_rule(ds, report):
    """A step given in the config is one uniform grid for every layout: the store's
    ``spectra_json`` and ``n_wavelengths`` say so, and the report's sampling table too."""
    import json

    spectra = json.loads(ds.attrs["spectra_json"])
    assert set(spectra) == {f"0,{li}" for li in range(3)}
    for record in spectra.values():
        assert record["rule"] == "given" and record["step_nm"] == 100.0
        assert record["wavelengths_nm"] == [500.0, 600.0]
        assert sum(record["weights"]) == pytest.approx(1.0)
    np.testing.assert_array_equal(ds.n_wavelengths.values, [[2, 2, 2]])
    summary = report[1]["summary"].read_text()
    assert "500–600 nm in 100 nm steps." in summary
    assert summary.count("| uniform 100 nm (2) |") == 3


def test_planned_rules_are_recorded_per_layout(tmp_path):
    """Without a step each layout sums its own planned rule; the store records the rule, its
    nodes and weights and the planner's reason, and the report lists them per layout."""
    import json

    from lfjax.sweep.compute import spectral_plans, sweep_spectra

    # 3x3 and 4x4: their planned Gauss rules differ (6 and 5 nodes); the natural view's
    # would be 11, each node its own FFT band of the compiled chunk function
    config = config_from_dict({**TINY, "population": {"n_eyes": 1, "seed": 0},
                               "display": {"layouts": ["3x3", "4x4"], "depth_offsets_D": [0.0]},
                               "spectrum": {"wavelengths_nm": [400.0, 700.0]},
                               "run": {"chunk_size": 2}})
    path = tmp_path / "planned.zarr"
    run_sweep(config, path, progress=False)
    stored = open_store(path)
    spectra = json.loads(stored.attrs["spectra_json"])
    plans, expected = spectral_plans(config), sweep_spectra(config)
    for (pi, li), spectrum in expected.items():
        record = spectra[f"{pi},{li}"]
        assert record["rule"] == plans[(pi, li)].spectral_rule
        np.testing.assert_allclose(record["wavelengths_nm"], np.asarray(spectrum.wavelengths_nm))
        np.testing.assert_allclose(record["weights"], np.asarray(spectrum.weights), rtol=1e-6)
        assert int(stored.n_wavelengths.values[pi, li]) == spectrum.n_wavelengths
    from lfjax.sweep.store import stored_spectra

    resumed = stored_spectra(path, config)  # what a resumed sweep sums: the stored rules
    for key, spectrum in expected.items():
        np.testing.assert_allclose(resumed[key].wavelengths_nm, spectrum.wavelengths_nm)
        np.testing.assert_allclose(resumed[key].weights, spectrum.weights, rtol=1e-6)
    assert spectra["0,0"]["n_wavelengths"] != spectra["0,1"]["n_wavelengths"]  # its own
    gauss = spectra["0,1"]
    assert gauss["rule"] == "gauss" and gauss["step_nm"] is None  # the 4x4 views
    assert "Gauss rule in V(λ)" in gauss["reason"]
    summary = sr.sweep_report(path, tmp_path / "report", draws=30, seed=1)["summary"].read_text()
    assert "sampled per layout" in summary
    assert f"| Gauss rule in V(λ), {gauss['n_wavelengths']} nodes |" in summary
    nodes = ", ".join(f"{w:.1f}" for w in gauss["wavelengths_nm"])
    assert f"3 mm 4x4: Gauss rule in V(λ), {gauss['n_wavelengths']} nodes: {nodes}." in summary


def test_a_store_without_recorded_rules_resumes_on_its_one_grid(store, tmp_path):
    """A store made before rules were recorded per layout resumes on its one recorded grid
    with V(λ) weights (what its chunks summed), not on a rule planned now."""
    import zarr

    from lfjax.model.spectral import make_spectrum
    from lfjax.sweep.store import stored_spectra

    old = tmp_path / "old.zarr"
    shutil.copytree(store, old)
    group = zarr.open_group(str(old), mode="r+", zarr_format=2)
    del group.attrs["spectra_json"]
    zarr.consolidate_metadata(str(old), zarr_format=2)
    config = config_from_dict(TINY)
    spectra = stored_spectra(old, config)
    assert set(spectra) == {(0, 0), (0, 1), (0, 2)}
    expected = make_spectrum([500.0, 600.0], config.options)
    for spectrum in spectra.values():
        np.testing.assert_allclose(spectrum.wavelengths_nm, expected.wavelengths_nm)
        np.testing.assert_allclose(spectrum.weights, expected.weights, rtol=1e-12)


def test_flat_curves_are_left_out_and_said(ds):
    """A store written before lfjax refused views outside the calculation pupil holds VSOTF
    exactly 1 at every state for such a layout: the report must not show its "peak"."""
    bad = ds.copy()
    vs = ds.vsotf.load().copy()
    window = vs.sel(layout="3x3").notnull()
    vs.loc[dict(layout="3x3")] = vs.sel(layout="3x3").where(~window, 1.0)
    bad["vsotf"] = vs
    flat = sr.flat_curves(bad)
    assert flat.sel(layout="3x3", metric="vsotf").all() and not flat.sel(layout="2x2").any()
    assert not sr.flat_curves(ds).any()
    table = sr.percentile_table(bad)
    assert table[(table.layout == "3x3") & (table.metric == "vsotf")].empty
    pd.testing.assert_frame_equal(
        table[table.layout != "3x3"].reset_index(drop=True),
        sr.percentile_table(ds).query("layout != '3x3'").reset_index(drop=True))
    assert [row[:4] for row in sr.flat_curve_cells(bad)] == [(3.0, "3x3", "vsotf", N_EYES)]
    assert "some curves have none (3 mm 3x3" in sr._ten_eye_reason(bad, 10)
