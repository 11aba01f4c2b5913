"""lfjax.reproduce.run: the stages of ``reproduce``, its output folder's checks and its
staging (the study itself is replaced here: a failure or a refusal before any work)."""

import pytest

from lfjax.reproduce import StudyConfig
from lfjax.reproduce import run


def test_the_stages_follow_the_parts_asked_for():
    config = StudyConfig.quick()
    plain = run.stage_names(config)
    assert plain[0] == "eyes" and plain[-3:] == ["tables", "figures", "report"]
    assert [f"through-focus {n}" for n in config.layouts] == plain[1:1 + len(config.layouts)]
    more = run.stage_names(config, population_store="pop.zarr", display_effects_eyes=1)
    assert "population: samples of the study's size" in more
    assert more[-5:-3] == ["display effects", "display: 2x2 lenslet sweep"]


def test_the_stage_bar_times_each_stage_it_ends():
    bar = run.StageBar(["a", "b", "c"], progress=False)
    bar.stage("a")
    bar.stage("b")
    bar.note("a long stage's scene")
    bar.stage("c")
    bar.finish()
    bar.close()
    assert list(bar.timings) == ["a", "b"] and all(t >= 0 for t in bar.timings.values())


def test_force_replaces_only_an_earlier_reproduction(tmp_path):
    out = tmp_path / "res"
    out.mkdir()
    (out / "mine.txt").write_text("not a reproduction")
    with pytest.raises(run.OutputError, match="not empty"):
        run.check_output_dir(out)
    with pytest.raises(run.OutputError, match="was not written by lfjax reproduce"):
        run.check_output_dir(out, force=True)
    (out / run.MARKER_FILE).write_text("")
    assert run.check_output_dir(out, force=True) == out
    with pytest.raises(run.OutputError, match="is not a folder"):
        run.check_output_dir(out / "mine.txt")


def test_a_failed_run_leaves_no_folder_and_no_staging(tmp_path, monkeypatch):
    def fails(config, stage=None):
        stage("natural")
        raise RuntimeError("simulated failure")

    monkeypatch.setattr(run, "run_study", fails)
    with pytest.raises(RuntimeError, match="simulated failure"):
        run.reproduce(tmp_path / "new" / "res", StudyConfig.quick(n_eyes=1), progress=False)
    assert list(tmp_path.iterdir()) == []


def test_the_room_asked_grows_with_the_eyes():
    few = run.estimated_output_bytes(StudyConfig.quick(n_eyes=1))
    assert run.estimated_output_bytes(StudyConfig.quick(n_eyes=3)) == few + 2 * 4 * 2**20
