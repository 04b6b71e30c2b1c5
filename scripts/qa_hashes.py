"""Equivalence fingerprint of the graph and QA engines (for refactors): prints one sha256 per part.

Parts: the stored scene graphs of toy scenes; every relation instance the graph query index answers
(GraphIndex.instances over the registry, undecided ones included); the QA pairs generate_qa makes from
those graphs with the default recipe's templates (single and multi-view); and verify's verdicts on them.
Run it in two checkouts (PYTHONPATH=<checkout>) and compare the lines.
Usage: python scripts/qa_hashes.py [N_SCENES]
"""

from __future__ import annotations

import hashlib
import json
import sys

import numpy as np


def main(n: int) -> None:
    from refspatial_gen.core.model import Sample
    from refspatial_gen.graph import build_graph
    from refspatial_gen.graph.query import GraphIndex
    from refspatial_gen.graph.relations import REGISTRY
    from refspatial_gen.qa import generate_qa, verify_sample
    from refspatial_gen.qa.bench import default_config
    from refspatial_gen.sources.toy import toy_frame

    cfg = default_config()
    h = {k: hashlib.sha256() for k in ("graphs", "facts", "qa", "verify")}
    n_qa = 0
    for i in range(n):
        rng = np.random.default_rng(1000 + i)
        f = toy_frame(rng, int(rng.integers(4, 10)), frame_id=f"toy:{i:06d}")
        boxes = [(o.category, o.attributes["color"], o.box) for o in f.objects]
        f2 = toy_frame(rng, 0, frame_id=f"toy:{i:06d}:v1", boxes=boxes)
        f.scene_id = f2.scene_id = f"scene{i}"
        g, g2 = build_graph(f), build_graph(f2)
        h["graphs"].update(json.dumps(g.to_json(), sort_keys=True).encode())
        gi = GraphIndex(g, f)
        for rid in sorted(REGISTRY):
            for fa in gi.instances(rid, decided_only=False):
                h["facts"].update(repr((fa.relation, fa.args, fa.holds, round(float(fa.value), 9),
                                        round(float(fa.margin), 9))).encode())
        for frames, graphs in (([f], [g]), ([f, f2], [g, g2])):
            qa = generate_qa(frames, graphs, np.random.default_rng(i), cfg)
            n_qa += len(qa)
            for q in qa:
                h["qa"].update(json.dumps(q.to_json(), sort_keys=True).encode())
            s = Sample(sample_id=f"s{i}", frames=frames, graphs=graphs, qa=qa, unit_key=f"u{i}", meta={})
            h["verify"].update(json.dumps(verify_sample(s), sort_keys=True).encode())
    for k, v in h.items():
        print(f"{k:8s} {v.hexdigest()}")
    print(f"qa_pairs {n_qa}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 60)
