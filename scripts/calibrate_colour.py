"""Agreement of the colour namer with known colours on real pixels (the figures in docs/quality.md).

Usage: .venv/bin/python scripts/calibrate_colour.py SHARD_DIR [--labels LABELS.jsonl] [--json]
- SHARD_DIR of a simulated run: every object whose source colour (`attributes["color"]`, the colour it was
  rendered with) is a basic term is a known colour ("silver" counts as gray); textured objects are skipped.
- --labels: JSON lines {"sample": ..., "frame": ..., "object": id, "colour": word|null} judged by eye
  (null: a person would give no single colour word), for photos.
Prints, for the graph's stored colour words (the namer the run used) and for this checkout's namer: named
share, agreement with the known colour among the named, and the share named with a wrong word.
"""

from __future__ import annotations

import argparse
import glob
import json
from collections import Counter

from refspatial_gen.graph.colour import VOCABULARY, colour_word, image_white, mask_pixels
from refspatial_gen.shards.reader import read_samples

ALIAS = {"silver": "gray", "grey": "gray"}


def rows(shard_dir: str, labels: dict | None):
    for shard in sorted(glob.glob(shard_dir + "/shard-*.mcap")):
        for s in read_samples(shard):
            nodes = {(g.frame_id, n.object_id): n for g in s.graphs for n in g.nodes}
            for f in s.frames:
                for o in f.objects:
                    if labels is not None:
                        key = (s.sample_id, f.frame_id, o.id)
                        if key not in labels:
                            continue
                        truth = labels[key]
                    else:
                        c = ALIAS.get(o.attributes.get("color"), o.attributes.get("color"))
                        if c not in VOCABULARY or o.attributes.get("textured") or o.mask is None:
                            continue
                        truth = c
                    n = nodes.get((f.frame_id, o.id))
                    if o.mask is None or n is None or o.mask.area < 20:
                        continue
                    m = o.mask.decode()
                    new = colour_word(mask_pixels(f.rgb, m), None, o.category, white=image_white(f.rgb))[0]
                    yield o.category, truth, n.attributes.get("color"), new


def summary(rs, k):
    n = len(rs)
    named = [r for r in rs if r[k] is not None]
    right = sum(r[k] == r[1] for r in named)
    return {"objects": n, "named": len(named), "named_share": round(len(named) / max(n, 1), 3),
            "agree": round(right / max(len(named), 1), 3), "wrong_share": round((len(named) - right) / max(n, 1), 3)}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("shards")
    ap.add_argument("--labels")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    labels = None
    if a.labels:
        labels = {}
        for line in open(a.labels):
            d = json.loads(line)
            labels[(d["sample"], d["frame"], d["object"])] = d["colour"]
    rs = list(rows(a.shards, labels))
    out = {"stored": summary(rs, 2), "namer": summary(rs, 3),
           "confusions": Counter(f"{t}->{w}" for _, t, _, w in rs if w is not None and w != t).most_common(12)}
    print(json.dumps(out, indent=None if a.json else 1))


if __name__ == "__main__":
    main()
