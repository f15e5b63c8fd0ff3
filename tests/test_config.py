"""Config loading: YAML errors, strict schema with did-you-mean, overrides, relative paths."""

import pytest

from synthkit.config import apply_overrides, load_yaml
from synthkit.errors import ConfigError, InputError
from synthkit.runner import load_method_config


def test_empty_file(tmp_path):
    path = tmp_path / "empty.yaml"
    path.write_text("   \n# only a comment\n")
    with pytest.raises(ConfigError, match=r"empty\.yaml: config file is empty"):
        load_yaml(path)


def test_non_mapping(tmp_path):
    path = tmp_path / "list.yaml"
    path.write_text("- a\n- b\n")
    with pytest.raises(ConfigError, match=r"list\.yaml: top level must be a mapping.*not a list"):
        load_yaml(path)


def test_syntax_error_names_line(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("method: echo\nimage: [a, b\n")
    with pytest.raises(ConfigError, match=r"bad\.yaml: YAML syntax error at line \d+"):
        load_yaml(path)


def test_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="config file not found"):
        load_yaml(tmp_path / "nope.yaml")


def test_overrides_nested_and_typed():
    data = {"a": {"b": 1}, "c": "x"}
    out = apply_overrides(data, ["a.b=2.5", "d.e=[1, 2]", "c=true"])
    assert out == {"a": {"b": 2.5}, "c": True, "d": {"e": [1, 2]}}
    assert data == {"a": {"b": 1}, "c": "x"}


@pytest.mark.parametrize("bad", ["novalue", "=3", "a..b=1"])
def test_override_syntax(bad):
    with pytest.raises(ConfigError, match="expected key.path=value"):
        apply_overrides({}, [bad])


def test_valid_config_resolves_relative_paths(echo_config):
    method, cfg, inputs = load_method_config(echo_config)
    assert method == "echo"
    assert cfg.image == (echo_config.parent / "in.png").resolve()
    assert inputs == [cfg.image]
    assert cfg.mode == "invert" and cfg.gain == 1.0 and cfg.filter.sigma == 1.0 and cfg.seed == 0


def test_unknown_top_level_key_did_you_mean(echo_config):
    with pytest.raises(ConfigError, match=r"echo\.yaml: unknown key 'gian' \(did you mean 'gain'\?\)"):
        load_method_config(echo_config, overrides=["gian=2"])


def test_unknown_nested_key_full_path(echo_config):
    with pytest.raises(ConfigError, match=r"unknown key 'filter\.sigam' \(did you mean 'filter\.sigma'\?\)"):
        load_method_config(echo_config, overrides=["filter.sigam=2"])


def test_unknown_key_without_close_match_lists_known(echo_config):
    with pytest.raises(ConfigError, match=r"unknown key 'zzz' \(known keys: .*gain.*\)"):
        load_method_config(echo_config, overrides=["zzz=1"])


def test_range_error_names_key_and_value(echo_config):
    with pytest.raises(ConfigError, match=r"gain: Input should be less than or equal to 10 \(got 11\)"):
        load_method_config(echo_config, overrides=["gain=11"])


def test_choice_error(echo_config):
    with pytest.raises(ConfigError, match=r"mode: Input should be 'copy' or 'invert' \(got 'flip'\)"):
        load_method_config(echo_config, overrides=["mode=flip"])


def test_missing_input_file_is_input_error(echo_config):
    with pytest.raises(InputError, match=r"echo\.yaml: image: file not found: .*missing\.png \(got 'missing\.png'\)"):
        load_method_config(echo_config, overrides=["image=missing.png"])


def test_config_error_before_missing_file_stays_config_error(echo_config):
    with pytest.raises(ConfigError, match=r"gain: Input should be less than or equal to 10"):
        load_method_config(echo_config, overrides=["image=missing.png", "gain=11"])


def test_missing_required_key(tmp_path, echo_method):
    path = tmp_path / "c.yaml"
    path.write_text("method: echo\n")
    with pytest.raises(ConfigError, match="missing required key 'image'"):
        load_method_config(path)


def test_unknown_method(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("method: retargt\n")
    with pytest.raises(ConfigError, match="unknown method 'retargt'"):
        load_method_config(path)


def test_method_mismatch(echo_config):
    with pytest.raises(ConfigError, match="does not match the subcommand 'retarget'"):
        load_method_config(echo_config, method="retarget")


def test_seed_override_and_range(echo_config):
    _, cfg, _ = load_method_config(echo_config, seed=7)
    assert cfg.seed == 7
    with pytest.raises(ConfigError, match="seed: Input should be greater than or equal to 0"):
        load_method_config(echo_config, overrides=["seed=-1"])
