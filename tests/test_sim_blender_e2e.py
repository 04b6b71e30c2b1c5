"""recipes/sim_blender.yaml end to end at 96x72 with 4 samples: every question verifies, the shards are
byte-identical for 1 and 2 workers (each worker process has its own Blender), and the objects (ids,
categories, masks, boxes) are the ones the MuJoCo renderer gives for the same units. The QA text may
differ: colour words come from the pixels (graph/colour.py), and the pictures differ."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from refspatial_gen.shards.reader import read_sample_meta
from refspatial_gen.tools.verify_dir import verify_dir
from tests.helpers.runs import output_digest

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[1]


def _small_recipe(tmp_path: Path, renderer: str = "blender") -> Path:
    text = (REPO / "recipes" / "sim_blender.yaml").read_text()
    for a, b in (
        ("width: 640", "width: 96"),
        ("height: 480", "height: 72"),
        ("samples: 16 ", "samples: 4 "),
        ("templates/", f"{REPO}/recipes/templates/"),
        ("renderer: blender", f"renderer: {renderer}"),
    ):
        assert a in text, a
        text = text.replace(a, b)
    p = tmp_path / f"sim_{renderer}_small.yaml"
    p.write_text(text)
    return p


def _shards(recipe: Path, out: Path, workers: int) -> None:
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "refspatial_gen.cli",
            "shards",
            "--recipe",
            str(recipe),
            "--out",
            str(out),
            "--scenes",
            "4",
            "--workers",
            str(workers),
            "--quiet",
            "--strict",
            "--no-report",
        ],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr[-2000:]


def _labels(out: Path) -> list:
    """Per sample and frame: the objects' ids, categories, masks and 3D boxes."""
    return [
        [
            [
                (o["id"], o["category"], json.dumps(o["mask"], sort_keys=True), json.dumps(o["box"], sort_keys=True))
                for o in f["objects"]
            ]
            for f in s["frames"]
        ]
        for shard in sorted(out.glob("shard-*.mcap"))
        for s in read_sample_meta(shard)
    ]


def test_sim_blender_recipe_verifies_and_is_byte_identical_across_workers(tmp_path):
    from tests.test_sim_blender import _need_blender

    _need_blender()
    recipe = _small_recipe(tmp_path)
    _shards(recipe, tmp_path / "w1", 1)
    _shards(recipe, tmp_path / "w2", 2)
    a, b = output_digest(tmp_path / "w1"), output_digest(tmp_path / "w2")
    assert len(a) >= 2 and a == b
    summary = verify_dir(tmp_path / "w1")
    assert summary["qa_pairs"] > 0 and summary["failed"] == 0, summary["failures"][:5]
    samples = [s for shard in sorted((tmp_path / "w1").glob("shard-*.mcap")) for s in read_sample_meta(shard)]
    assert len(samples) == 4  # no unit dropped by the agreement check (--strict does not fail on drops)
    checks = [f["meta"]["render_check"] for s in samples for f in s["frames"] if f["meta"]["renderer"] == "blender"]
    assert len(checks) == sum(len(s["frames"]) for s in samples) > 0  # every frame is Blender's and was checked
    assert all(c["mask_iou_min"] >= 0.9 and c["depth_agree"] >= 0.97 for c in checks)  # the recipe's thresholds
    _shards(_small_recipe(tmp_path, "mujoco"), tmp_path / "mj", 1)
    assert _labels(tmp_path / "mj") == _labels(tmp_path / "w1")
