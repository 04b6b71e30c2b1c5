"""Exports are atomic and self-consistent (#22 defects 1 and 6): no stale pixels, no name collisions,
a check that compares what the export references with the shards, marked images for visual choice."""

from __future__ import annotations

import hashlib
import json

import pytest

from refspatial_gen.cli import main
from refspatial_gen.core.model import QAPair
from refspatial_gen.shards import ShardWriter, iter_raw, write_index
from refspatial_gen.shards.export import EXPORTERS, export
from refspatial_gen.shards.export_files import ExportError, sample_stem
from refspatial_gen.sources.toy_samples import make_samples


def _write_dir(d, samples, image_format="png"):
    w = ShardWriter(d / "shard-00000.mcap", image_format=image_format)
    for s in samples:
        w.write(s)
    write_index(d, [i.to_dict() for i in w.finish()], {"seed": 0})
    return d


def _stored(d) -> dict[tuple[str, int], str]:
    """{(sample_id, view): sha256 of the stored image bytes}."""
    out = {}
    for raw in iter_raw(d / "shard-00000.mcap"):
        for v in range(raw.views):
            out[(raw.header["sample_id"], v)] = hashlib.sha256(raw.image_bytes(v)[0]).hexdigest()
    return out


def _sha(p) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


def _refspatial_pairs(out):
    """(record id, image path) for every image every record names."""
    return [(r["id"], out / "image" / im) for f in sorted(out.glob("*.json")) for r in json.loads(f.read_text())
            for im in r["image"]]


@pytest.fixture(scope="module")
def two_datasets(tmp_path_factory):
    a = _write_dir(tmp_path_factory.mktemp("a"), make_samples(3, seed=1, width=64, height=48))
    b = _write_dir(tmp_path_factory.mktemp("b"), make_samples(3, seed=2, width=64, height=48))
    return a, b


def test_reexport_into_used_folder_never_pairs_new_text_with_old_pixels(two_datasets, tmp_path, capsys):
    """Defect 1: the second export used to keep the first one's images under the same names."""
    a, b = two_datasets
    out = tmp_path / "export"
    assert main(["export", str(a), "--format", "refspatial", "--out", str(out)]) == 0
    first = {p.name: _sha(p) for p in (out / "image").iterdir()}
    # same sample ids, different pixels: refused without --overwrite, folder untouched
    assert main(["export", str(b), "--format", "refspatial", "--out", str(out)]) == 1
    assert "not empty" in capsys.readouterr().err
    assert {p.name: _sha(p) for p in (out / "image").iterdir()} == first
    assert main(["export", str(b), "--format", "refspatial", "--out", str(out), "--overwrite"]) == 0
    stored = _stored(b)
    for _rid, img in _refspatial_pairs(out):
        if "_marks" not in img.name:
            sid_view = [k for k in stored if img.name.startswith(sample_stem(k[0]) + f"_v{k[1]}.")]
            assert sid_view and _sha(img) == stored[sid_view[0]]
    assert not list(tmp_path.glob(".export.*"))  # no temporary folder left behind


@pytest.mark.parametrize("fmt", sorted(EXPORTERS))
def test_overwrite_replaces_everything(two_datasets, tmp_path, fmt):
    if fmt == "hf":
        pytest.importorskip("datasets")
    a, b = two_datasets
    out = tmp_path / "x"
    out.mkdir()
    (out / "stale.json").write_text("[]")
    with pytest.raises(ExportError, match="not empty"):
        export(a, fmt, out)
    export(a, fmt, out, overwrite=True)
    assert not (out / "stale.json").exists()


def test_ids_differing_only_in_non_ascii_get_distinct_files(tmp_path):
    samples = make_samples(3, seed=4, width=64, height=48)
    samples[0].sample_id, samples[1].sample_id, samples[2].sample_id = "scène:é", "scène:è", "plain-id_01"
    d = _write_dir(tmp_path / "ds", samples)
    assert len({sample_stem(s.sample_id) for s in samples}) == 3
    assert sample_stem("plain-id_01") == "plain-id_01"  # safe ids are kept as they are
    stored = _stored(d)
    for fmt in ("refspatial", "jsonl"):
        out = tmp_path / fmt
        export(d, fmt, out)
        names = {p.name for p in (out / "image").iterdir() if "_marks" not in p.name}
        assert len(names) == 3
        for (sid, v), h in stored.items():
            assert _sha(out / "image" / f"{sample_stem(sid)}_v{v}.png") == h


def test_stems_are_stable_and_distinct():
    assert sample_stem("toy:000001") == sample_stem("toy:000001")
    assert sample_stem("toy:000001") != sample_stem("toy/000001") != sample_stem("toy_000001")
    assert sample_stem("a.b", allow_dot=False) != sample_stem("a_b", allow_dot=False)
    assert all(c.isascii() for c in sample_stem("场景:1"))


def test_export_check_compares_images_with_shards(two_datasets, tmp_path, monkeypatch):
    """The export's own check catches an image whose bytes are not the shard's, and nothing lands."""
    import refspatial_gen.shards.export_refspatial as er

    a, _ = two_datasets
    real = er.write_new

    def sabotage(path, data):
        real(path, data[:-1] + bytes([data[-1] ^ 1]) if path.suffix == ".png" and "image" in path.parts
             and "_marks" not in path.name and path.name.endswith("_v0.png") and "000001" in path.name else data)

    monkeypatch.setattr(er, "write_new", sabotage)
    with pytest.raises(ExportError, match="differs from the stored view"):
        export(a, "refspatial", tmp_path / "out")
    assert not (tmp_path / "out").exists()
    assert not list(tmp_path.iterdir())


def test_jsonl_visual_choice_points_at_the_marked_image(tmp_path):
    """Defect 6 (first half): the question is about drawn labels, so the line must name the marked copy."""
    s = make_samples(1, seed=7, width=96, height=72, n_qa=1)[0]
    base, o = s.qa[0], s.frames[0].objects
    s.qa.append(QAPair(f"{base.qa_id}:vc", "visual_choice", "vc.t", "Which marked object is leftmost? (A) (B)", "(A)",
                       {"kind": "choice", "marks": [{"label": "A", "object_id": o[0].id, "style": "box"},
                                                    {"label": "B", "object_id": o[1].id, "style": "point"}]},
                       ["left_of"], 2, base.frame_ids, base.image_size))
    d = _write_dir(tmp_path / "ds", [s])
    out = tmp_path / "j"
    export(d, "jsonl", out)
    lines = {x["id"]: x for x in map(json.loads, (out / "qa.jsonl").read_text().splitlines())}
    vc, plain = lines[f"{base.qa_id}:vc"], lines[base.qa_id]
    assert vc["image"][0].endswith("_marks1.png") and plain["image"][0] == f"{sample_stem(s.sample_id)}_v0.png"
    assert _sha(out / "image" / vc["image"][0]) != _sha(out / "image" / plain["image"][0])
    # the same marked image as the RefSpatial export draws
    export(d, "refspatial", tmp_path / "r")
    rec = json.loads((tmp_path / "r" / "visual_choice.json").read_text())[0]
    assert rec["image"] == vc["image"]
    assert _sha(tmp_path / "r" / "image" / rec["image"][0]) == _sha(out / "image" / vc["image"][0])


def test_cli_format_choices_come_from_the_table(capsys):
    with pytest.raises(SystemExit):
        main(["export", "x", "--format", "nope", "--out", "y"])
    err = capsys.readouterr().err
    for name in EXPORTERS:
        assert name in err


def test_overwrite_never_targets_the_shards_themselves(two_datasets, tmp_path, monkeypatch):
    a, _ = two_datasets
    for target in (a, a.parent, tmp_path):
        monkeypatch.chdir(tmp_path)
        with pytest.raises(ExportError, match="refusing"):
            export(a, "jsonl", target, overwrite=True)
    assert (a / "index.json").is_file() and (a / "shard-00000.mcap").is_file()
