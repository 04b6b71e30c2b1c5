"""Exports: RefSpatial layout (RoboRefer loader rules), WebDataset read-back, JSON lines; CLI errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from refspatial_gen.cli import main
from refspatial_gen.core.model import QAPair
from refspatial_gen.shards import ShardWriter, write_index
from refspatial_gen.shards.export import export
from refspatial_gen.shards.export_refspatial import check_roborefer_layout, inverse_depth_png
from refspatial_gen.sources.toy_samples import make_samples


@pytest.fixture(scope="module")
def shard_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("exp")
    samples = make_samples(4, seed=31, width=160, height=120, n_qa=5) + make_samples(1, seed=32, views=2, width=160, height=120)
    samples[-1].sample_id = "toy:mv"
    big = samples[0]
    # 20 QA pairs of one family in one sample -> two records (15 + 5)
    base = big.qa[0]
    big.qa = big.qa + [QAPair(f"{base.qa_id}:x{i}", "identify", "identify.t", f"What is at <image> spot {i}?", "a box",
                              {"kind": "choice"}, [], 1, base.frame_ids, base.image_size) for i in range(20)]
    # a visual-choice pair whose image needs marks
    o = big.frames[0].objects
    big.qa.append(QAPair(f"{base.qa_id}:vc", "visual_choice", "vc.t", "Which marked object is leftmost? (A) (B)", "(A)",
                         {"kind": "choice", "marks": [{"label": "A", "object_id": o[0].id, "style": "box"},
                                                      {"label": "B", "object_id": o[1].id, "style": "point"}]},
                         ["left_of"], 2, base.frame_ids, base.image_size))
    w = ShardWriter(d / "shard-00000.mcap")
    for s in samples[:3]:
        w.write(s)
    infos = w.finish()
    w = ShardWriter(d / "shard-00001.mcap", image_format="png")
    for s in samples[3:]:
        w.write(s)
    infos += w.finish()
    write_index(d, [i.to_dict() for i in infos], {"seed": 0})
    return d, samples


def test_refspatial_layout_passes_roborefer_rules(shard_dir, tmp_path):
    d, samples = shard_dir
    res = export(d, "refspatial", tmp_path)
    assert check_roborefer_layout(tmp_path) == []
    assert res["qa_pairs"] == sum(len(s.qa) for s in samples)
    ident = json.loads((tmp_path / "identify.json").read_text())
    assert sorted(len(r["conversations"]) // 2 for r in ident) == [5, 15]
    assert all("<image>" not in t["value"] for r in ident for t in r["conversations"])
    # reasoning records carry think with traces and key steps, one per pair
    think = [r for f in tmp_path.glob("*.json") for r in json.loads(f.read_text()) if "think" in r]
    assert think and all(len(r["think"]) == len(r["conversations"]) // 2 for r in think)
    assert all(t["trace"].startswith("<think>") and t["key_steps"] for r in think for t in r["think"])
    # multi-view record lists both images and both depth maps
    mv = [r for f in tmp_path.glob("*.json") for r in json.loads(f.read_text()) if r["id"].startswith("toy_mv")]
    assert mv and all(len(r["image"]) == 2 == len(r["depth"]) for r in mv)
    # visual choice uses a marked copy that differs from the plain image
    vc = json.loads((tmp_path / "visual_choice.json").read_text())
    assert len(vc) == 1 and "marks" in vc[0]["image"][0]
    import cv2

    marked = cv2.imread(str(tmp_path / "image" / vc[0]["image"][0]))
    plain = cv2.imread(str(tmp_path / "image" / (vc[0]["image"][0].split("_marks")[0] + ".jpg")))
    assert marked.shape == plain.shape and np.abs(marked.astype(int) - plain.astype(int)).sum() > 0
    cv2.imwrite("/tmp/refspatial_marks_preview.png", marked)


def test_checker_catches_violations(shard_dir, tmp_path):
    d, _ = shard_dir
    export(d, "refspatial", tmp_path)
    f = tmp_path / "locate.json"
    recs = json.loads(f.read_text())
    recs[0]["conversations"][0]["value"] += " <image>"
    recs[0]["conversations"][1]["from"] = "human"
    f.write_text(json.dumps(recs))
    (tmp_path / "bad.json").write_text(json.dumps({"id": 1}))
    dep = tmp_path / "depth" / recs[1]["depth"][0]
    cv2 = pytest.importorskip("cv2")
    cv2.imwrite(str(dep), np.zeros((10, 10), np.uint8))
    errs = "\n".join(check_roborefer_layout(tmp_path))
    assert "not a list" in errs and "<image>" in errs and "expected 'gpt'" in errs
    assert "8-bit 3-channel" in errs and "is (10, 10)" in errs


def test_inverse_depth_png():
    import cv2

    depth = np.array([[0.5, 1.0], [2.0, 0.0]], np.float32)
    img = cv2.imdecode(np.frombuffer(inverse_depth_png(depth), np.uint8), cv2.IMREAD_UNCHANGED)
    assert img.shape == (2, 2, 3) and img.dtype == np.uint8
    g = img[..., 0]
    assert g[0, 0] == 255 and g[1, 0] == 0 and g[1, 1] == 0 and 0 < g[0, 1] < 255
    assert g[0, 1] == round((1 / 1.0 - 0.5) / (2.0 - 0.5) * 255)


def test_webdataset_reads_back_every_sample(shard_dir, tmp_path):
    wds = pytest.importorskip("webdataset")
    d, samples = shard_dir
    res = export(d, "webdataset", tmp_path)
    assert res["samples"] == len(samples)
    ds = wds.WebDataset([str(tmp_path / t) for t in res["tars"]], shardshuffle=False).decode("rgb8")
    got = list(ds)
    assert len(got) == len(samples)
    by_id = {s.sample_id: s for s in samples}
    for rec in got:
        meta = rec["json"]
        s = by_id[meta["sample_id"]]
        assert [q["qa_id"] for q in meta["qa"]] == [q.qa_id for q in s.qa]
        for v, f in enumerate(s.frames):
            rgb = rec[f"rgb{v}.png"] if f"rgb{v}.png" in rec else rec[f"rgb{v}.jpg"]
            assert rgb.shape == f.rgb.shape
            assert np.array_equal(rec[f"depth{v}.npy"], f.depth)
    # deterministic tar bytes
    export(d, "webdataset", tmp_path / "again")
    assert (tmp_path / res["tars"][0]).read_bytes() == (tmp_path / "again" / res["tars"][0]).read_bytes()


def test_jsonl(shard_dir, tmp_path):
    d, samples = shard_dir
    res = export(d, "jsonl", tmp_path)
    lines = [json.loads(x) for x in (tmp_path / "qa.jsonl").read_text().splitlines()]
    assert len(lines) == res["qa_pairs"] == sum(len(s.qa) for s in samples)
    multi = [x for x in lines if x["steps"] > 1 and x["family"] != "visual_choice"]
    assert multi and all(x["trace"].startswith("<think>") and x["key_steps"][0]["type"] == "Position" for x in multi)
    assert all((tmp_path / "image" / n).is_file() for x in lines for n in x["image"])


def test_cli_export_and_inspect(shard_dir, tmp_path, capsys):
    d, _ = shard_dir
    assert main(["export", str(d), "--format", "refspatial", "--out", str(tmp_path / "r")]) == 0
    assert main(["inspect", str(d / "shard-00000.mcap")]) == 0
    out = capsys.readouterr().out
    assert "3 samples" in out and "locate" in out


def test_cli_errors_name_the_file_without_traceback(shard_dir, tmp_path, capsys):
    d, _ = shard_dir
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"hello, not a shard" * 50)
    assert main(["inspect", str(junk)]) == 1
    err = capsys.readouterr().err
    assert str(junk) in err and "not an MCAP file" in err and "Traceback" not in err
    cut = tmp_path / "cut.mcap"
    cut.write_bytes((d / "shard-00000.mcap").read_bytes()[:30000])
    assert main(["inspect", str(cut)]) == 1
    err = capsys.readouterr().err
    assert str(cut) in err and "truncated" in err
    # a hash mismatch stops the export and names the shard
    import shutil

    bad = tmp_path / "bad"
    shutil.copytree(d, bad)
    data = bytearray((bad / "shard-00001.mcap").read_bytes())
    data[100] ^= 1
    (bad / "shard-00001.mcap").write_bytes(bytes(data))
    assert main(["export", str(bad), "--format", "jsonl", "--out", str(tmp_path / "j")]) == 1
    err = capsys.readouterr().err
    assert str(bad / "shard-00001.mcap") in err and "hash_mismatch" in err
