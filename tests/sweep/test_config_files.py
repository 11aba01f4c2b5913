"""lfjax.sweep.config_files: a sweep's configuration read from and written to TOML, its
template, and a store's recorded configuration compared with a sweep's."""

import pytest

from lfjax.sweep.config import SweepConfig
from lfjax.sweep.config_files import (
    config_differences,
    config_template,
    config_to_toml,
    load_config,
    with_new_defaults,
)
from lfjax.sweep.config_keys import SweepConfigError


def test_toml_written_reads_back_as_the_same_config(tmp_path):
    config = SweepConfig(n_eyes=3, pupil_diameters_mm=(3.0,), layouts=("natural", "2x2"))
    path = tmp_path / "pop.toml"
    path.write_text(config_to_toml(config))
    assert load_config(path) == config


def test_the_template_reads_as_the_default_config(tmp_path):
    path = tmp_path / "template.toml"
    path.write_text(config_template())
    assert load_config(path) == SweepConfig()


@pytest.mark.parametrize("text, problem", [(None, "does not exist"), ("", "sets nothing"),
                                           ("[population\n", "not valid TOML")])
def test_a_file_that_cannot_be_a_config_is_refused_in_words(tmp_path, text, problem):
    path = tmp_path / "pop.toml"
    if text is not None:
        path.write_text(text)
    with pytest.raises(SweepConfigError, match=problem):
        load_config(path)
    with pytest.raises(SweepConfigError, match="is a folder"):
        load_config(tmp_path)


def test_a_stored_record_without_a_new_key_reads_at_its_default():
    current = SweepConfig().as_dict()
    stored = {k: v for k, v in current.items() if k != "leakage_weight"}
    assert config_differences(with_new_defaults(stored), current) == []
    changed = dict(current, n_eyes=5)
    assert config_differences(changed, current) == [
        f"n_eyes: store has 5, config has {current['n_eyes']!r}"]
