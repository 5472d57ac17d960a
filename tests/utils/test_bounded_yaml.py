"""multiros.bounded_yaml: hostile YAML is one quick error, ordinary YAML loads as safe_load loads it."""

from __future__ import annotations

import time

import pytest
import yaml

from multiros.bounded_yaml import YamlBoundsError, load_yaml_bounded, read_yaml_bounded

LAUGHS = 'a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]\n' + "".join(
    f"{chr(98 + i)}: &{chr(98 + i)} [{','.join(['*' + chr(97 + i)] * 9)}]\n" for i in range(8))


def test_ordinary_yaml_loads_as_safe_load_does():
    text = "a: 1\nb: [1, 2.5, {c: x}]\nbase: &base {k: 1}\nother: *base\nnull_value:\nflag: true\n"
    assert load_yaml_bounded(text) == yaml.safe_load(text)
    assert load_yaml_bounded("") is None


@pytest.mark.parametrize(("text", "message"), [
    (LAUGHS, "expands to more than 50,000 values"),
    ("[" * 100 + "]" * 100, "nested deeper than 64 levels"),
    ("[" * 50_000 + "]" * 50_000, "not valid YAML|nested deeper"),  # libyaml stops at 1,000 levels
    ("n: [" + ",".join(["1"] * 100_000) + "]", "holds more than 50,000 values"),
    ("n: [" + ",".join(["1"] * 600_000) + "]", "larger than 1,048,576 bytes"),
    ("a: [1, 2\n", "not valid YAML: while parsing a flow sequence"),
    ("!!python/object:os.system {}", "not valid YAML"),
])
def test_hostile_yaml_is_one_line_quickly(text, message):
    start = time.monotonic()
    with pytest.raises(YamlBoundsError, match=message) as err:
        load_yaml_bounded(text)
    assert "\n" not in str(err.value) and len(str(err.value)) < 300
    assert time.monotonic() - start < 5.0  # a laughs file used to hang every command


def test_a_large_file_is_not_read_whole(tmp_path):
    big = tmp_path / "big.yaml"
    with big.open("w") as f:
        f.write("k: ")
        f.seek(200 * (1 << 20))  # a 200 MB file, sparse: only the first MiB and a byte are read
        f.write("x\n")
    with pytest.raises(YamlBoundsError, match="larger than 1,048,576 bytes"):
        read_yaml_bounded(big)
    (tmp_path / "latin1.yaml").write_bytes(b"k: \xff\n")
    with pytest.raises(YamlBoundsError, match="not UTF-8"):
        read_yaml_bounded(tmp_path / "latin1.yaml")
