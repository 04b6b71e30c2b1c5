"""The YAML loader is bounded: alias bombs, deep nesting, huge files, executable tags and special files are
RecipeErrors with a line, quickly, never a traceback, a hang or a command run."""

import os
import time

import pytest

from refspatial_gen.core.errors import RecipeError
from refspatial_gen.yamlpos import MAX_BYTES, load_yaml


def _bomb(levels: int) -> str:
    text = "a: &a [x, x, x, x, x, x, x, x, x]\n"
    for i in range(levels - 1):
        prev, cur = chr(97 + i), chr(98 + i)
        text += f"{cur}: &{cur} [{', '.join(['*' + prev] * 9)}]\n"
    return text


def test_alias_bomb_stops_at_once():
    t0 = time.perf_counter()
    with pytest.raises(RecipeError, match="after expanding aliases"):
        load_yaml("r.yaml", _bomb(9))
    assert time.perf_counter() - t0 < 10


def test_small_alias_use_still_works():
    data, _ = load_yaml("r.yaml", "base: &b {kind: toy}\nsources: [*b, *b]\n")
    assert data["sources"] == [{"kind": "toy"}, {"kind": "toy"}]


@pytest.mark.parametrize("text", ["x: " + "[" * 5000 + "]" * 5000, "x: " + "{a: " * 3000 + "1" + "}" * 3000,
                                  "".join("  " * i + f"k{i}:\n" for i in range(1500)) + "  " * 1500 + "v: 1\n"])
def test_deep_nesting_is_an_error_with_a_line(text):
    with pytest.raises(RecipeError, match="nested deeper than") as ei:
        load_yaml("r.yaml", text)
    assert ei.value.line is not None and ei.value.line >= 1


def test_size_limit(tmp_path):
    p = tmp_path / "big.yaml"
    p.write_text("a: 1\n#" + "x" * MAX_BYTES)
    with pytest.raises(RecipeError, match="limit"):
        load_yaml(p)


@pytest.mark.parametrize("text", ["a: !!python/object/apply:os.system ['touch PWNED']",
                                  "a: !!python/object:os.system {}", "a: !!python/name:os.system",
                                  "a: !!python/object/new:os.system [x]"])
def test_python_tags_never_execute(tmp_path, text, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(RecipeError):
        load_yaml("r.yaml", text)
    assert not (tmp_path / "PWNED").exists()


@pytest.mark.parametrize("text, needle", [("a: !!int abc", "cannot be read"), ("a: 1\n---\nb: 2", "another document"),
                                          ("a: 1\na: 2", "duplicate key"), ("a: b\x00", "unacceptable character"),
                                          ("[a]: 1", "plain scalars")])
def test_bad_scalars_and_structure(text, needle):
    with pytest.raises(RecipeError, match=needle):
        load_yaml("r.yaml", text)


def test_special_files_are_refused_without_reading(tmp_path):
    fifo = tmp_path / "fifo.yaml"
    os.mkfifo(fifo)  # opening it would block forever
    with pytest.raises(RecipeError, match="not a regular file"):
        load_yaml(fifo)
    with pytest.raises(RecipeError, match="not a regular file"):
        load_yaml("/dev/zero")
    with pytest.raises(RecipeError, match="not a regular file"):
        load_yaml(tmp_path)


def test_not_utf8(tmp_path):
    p = tmp_path / "r.yaml"
    p.write_bytes(b"a: \xff\n")
    with pytest.raises(RecipeError, match="not UTF-8"):
        load_yaml(p)
