"""Small real Samples for tests and benches: toy-source frames with hand-made graphs and QA pairs.

Why here (beside the toy source) and not in tests/: the shard bench (`make bench`) needs the same data when
no run output exists, and the shard stage must not import a source itself.
The QA pairs are real in the sense that matters for shards: each "locate" answer is the answer point of
its target's mask, so exports and readers can check geometry round trips.
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.core.mask import answer_pixel, normalise_point
from refspatial_gen.core.model import KeyStep, Node, QAPair, RelationFact, Sample, SceneGraph
from refspatial_gen.sources.toy import toy_frame


def make_sample(
    rng: np.random.Generator, idx: int, *, views: int = 1, width: int = 320, height: int = 240, n_qa: int = 3
) -> Sample:
    """One Sample of `views` toy frames (same boxes, different cameras when views > 1)."""

    first = toy_frame(rng, int(rng.integers(3, 6)), width, height, frame_id=f"toy:{idx:06d}:v0")
    frames = [first]
    boxes = [(o.category, o.attributes["color"], o.box) for o in first.objects]
    for v in range(1, views):
        frames.append(toy_frame(rng, 0, width, height, frame_id=f"toy:{idx:06d}:v{v}", boxes=boxes))
    graphs, qa = [], []
    for f in frames:
        nodes = []
        for o in f.objects:
            px = answer_pixel(o.mask.decode())
            nodes.append(
                Node(
                    o.id,
                    o.category,
                    {"color": o.attributes.get("color")},
                    [f"the {o.attributes.get('color')} {o.category}"],
                    normalise_point(px[0], px[1], f.camera.width, f.camera.height),
                )
            )
        facts = []
        if len(f.objects) >= 2:
            a, b = f.objects[0], f.objects[1]
            dx = float(f.camera.world_to_cam(a.box.center)[0, 0] - f.camera.world_to_cam(b.box.center)[0, 0])
            facts.append(RelationFact("left_of", (a.id, b.id), dx < 0, dx, 0.02))
        graphs.append(SceneGraph(f.frame_id, nodes, facts, [], {"scale": "tabletop"}))
    g0, f0 = graphs[0], frames[0]
    families = ["locate", "choice", "quantitative", "placement"]
    for j in range(n_qa):
        node = g0.nodes[j % len(g0.nodes)]
        fam = families[(idx + j) % len(families)]
        steps = 1 + (idx + j) % 3
        pt = node.point
        trace = ""
        keys: list[KeyStep] = []
        if steps > 1:
            keys = [KeyStep("Position", node.phrases[0], list(pt))]
            xy = f"({pt[0]:.3f}, {pt[1]:.3f})"
            trace = f"<think>[Position] [{node.phrases[0]}]: {xy}</think><answer>[{xy}]</answer>"
        qa.append(
            QAPair(
                qa_id=f"{f0.frame_id}:q{j}",
                family=fam,
                template=f"{fam}.t{j % 2}",
                question=f"Point to {node.phrases[0]}. Answer with a list of tuples [(x, y)] of normalised "
                "coordinates.",
                answer=f"[({pt[0]:.3f}, {pt[1]:.3f})]",
                answer_struct={"kind": "points", "points": [list(pt)]},
                relations=["left_of"] if j % 2 else [],
                steps=steps,
                frame_ids=[f.frame_id for f in frames],
                image_size=(f0.camera.width, f0.camera.height),
                program=[{"op": "select", "arg": node.phrases[0]}],
                trace=trace,
                key_steps=keys,
                checks=["point_in_mask"],
                targets=[node.object_id],
            )
        )
    return Sample(
        sample_id=f"toy:{idx:06d}",
        frames=frames,
        graphs=graphs,
        qa=qa,
        unit_key=f"toy:{idx:06d}",
        meta={"source": "toy", "views": views},
    )


def make_samples(n: int, seed: int = 0, **kw) -> list[Sample]:
    rng = np.random.default_rng(seed)
    return [make_sample(rng, i, **kw) for i in range(n)]
