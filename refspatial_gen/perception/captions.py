"""Object captions: colour and material words, ordinal and hierarchical captions, an optional VLM description.

RefSpatial gives every object of a picture hierarchical captions, from the category ("cup") through its
attributes ("red ceramic cup") to a phrase that singles it out among objects of its category by where it
is ("the third cup from the left", "the nearest cup"), because its pictures hold several objects of one
category. Here:
- colour: the project's colour namer on the object's own visible pixels (`graph.colour`, called, never
  copied: its decisions are the graph's);
- material: optional, CLIP/SigLIP zero-shot over `words` on a crop around the object, kept only when the
  best word leads the second by `min_margin`;
- ordinals: left-to-right by the centre of the visible mask, counted from the nearer side ("the second
  cup from the right"), near-to-far by the object's distance to the camera; an ordinal is written only
  when every neighbour in that order is at least `ORDER_MARGIN` away (a tie would make it wrong);
- description: optional, a local vision-language model's text (`vlm.py`), context only.
Stored on each object (`attributes`, `description`, `provenance["captions"]`) and as
`frame.meta["captions"]`. The graph still names colours itself for its phrases.
"""

from __future__ import annotations

from typing import Any

import numpy as np

ORDINALS = ("first", "second", "third", "fourth", "fifth", "sixth", "seventh", "eighth", "ninth", "tenth")
ORDER_MARGIN_PX = 0.02  # of the image width, between neighbours left to right
ORDER_MARGIN_M = 0.10  # metres, between neighbours near to far


def colour_of(rgb: np.ndarray, mask: np.ndarray, category: str | None = None) -> str | None:
    """The colour word of the pixels under `mask` (None when inconclusive): the graph's own namer, on the
    mask's bounding box as the scene graph crops it (the namer's edge erosion depends on the crop)."""
    from refspatial_gen.graph.colour import colour_word, image_white, mask_pixels

    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if len(rows) == 0:
        return None
    y0, y1, x0, x1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    px = mask_pixels(rgb[y0:y1, x0:x1], mask[y0:y1, x0:x1])
    return colour_word(px, category=category, white=image_white(rgb))[0]  # the graph's white level


def _separated(values: list[float], margin: float) -> bool:
    v = sorted(values)
    return all(b - a >= margin for a, b in zip(v, v[1:]))


def ordinal_captions(cats: list[str], xs: list[float], dists: list[float], width: int) -> list[list[str]]:
    """Per object, its ordinal captions among objects of its category (none for a category of one)."""
    out: list[list[str]] = [[] for _ in cats]
    for cat in sorted(set(cats)):
        idx = [i for i, c in enumerate(cats) if c == cat]
        n = len(idx)
        if n < 2:
            continue
        if n <= len(ORDINALS) and _separated([xs[i] for i in idx], ORDER_MARGIN_PX * width):
            order = sorted(idx, key=lambda i: xs[i])
            for r, i in enumerate(order):
                k, side = (r, "left") if r < (n + 1) // 2 else (n - 1 - r, "right")
                out[i].append(f"the {side}most {cat}" if k == 0 else f"the {ORDINALS[k]} {cat} from the {side}")
        if n <= len(ORDINALS) and _separated([dists[i] for i in idx], ORDER_MARGIN_M):
            order = sorted(idx, key=lambda i: dists[i])
            for r, i in enumerate(order):
                k, end = (r, "nearest") if r < (n + 1) // 2 else (n - 1 - r, "farthest")
                out[i].append(f"the {end} {cat}" if k == 0 else f"the {ORDINALS[k]} {end} {cat}")
    return out


def hierarchical(cat: str, attrs: dict[str, str], ordinals: list[str], unique: bool) -> list[str]:
    """Coarse to fine: category, attributes + category, then the ordinal phrases."""
    words = [attrs[k] for k in ("color", "material") if attrs.get(k)]
    out = [f"the {cat}" if unique else cat]
    if words:
        out.append(f"the {' '.join(words)} {cat}")
    return out + ordinals


def _crop(rgb: np.ndarray, bbox: tuple[float, float, float, float], pad: float = 0.1) -> np.ndarray:
    H, W = rgb.shape[:2]
    x0, y0, x1, y1 = bbox
    px, py = (x1 - x0) * pad, (y1 - y0) * pad
    a, b = int(max(0, np.floor(x0 - px))), int(max(0, np.floor(y0 - py)))
    c, d = int(min(W, np.ceil(x1 + px))), int(min(H, np.ceil(y1 + py)))
    return np.ascontiguousarray(rgb[b : max(d, b + 1), a : max(c, a + 1)])


def material_of(P, content: str, rgb: np.ndarray, bbox, cat: str) -> str | None:
    m = P.cfg["captions"]["material"]
    words = [str(w) for w in m["words"]]
    prompts = [f"a photo of a {w} {cat}" for w in words]
    box = [round(float(x), 1) for x in bbox]
    arr, _ = P.cached(
        "material",
        content,
        [box, prompts],
        lambda: ({"p": P.model("material").scores([_crop(rgb, bbox)], prompts)[0].astype(np.float32)}, {}),
    )
    p = arr["p"].astype(np.float64)
    order = np.argsort(-p, kind="stable")
    return words[int(order[0])] if len(p) < 2 or p[order[0]] - p[order[1]] >= m["min_margin"] else None


def description_of(P, content: str, rgb: np.ndarray, bbox, cat: str) -> str:
    v = P.cfg["captions"]["vlm"]
    prompt = v["prompt"].format(category=cat)
    box = [round(float(x), 1) for x in bbox]
    _, meta = P.cached(
        "vlm",
        content,
        [box, prompt, v["max_new_tokens"]],
        lambda: ({}, {"text": P.model("vlm").describe([_crop(rgb, bbox)], [prompt], v["max_new_tokens"])[0]}),
    )
    return str(meta["text"])


def caption_frame(frame, P, content: str) -> None:
    """Attributes, descriptions and hierarchical captions for every object of a frame built from a photo."""
    objs = frame.objects
    if not objs:
        return
    cam = frame.camera
    masks = [o.mask.decode() for o in objs]
    xs = [float(np.nonzero(m)[1].mean()) if m.any() else 0.0 for m in masks]
    dists = [float(np.linalg.norm(o.box.center - cam.position)) for o in objs]
    cats = [o.category for o in objs]
    ords = ordinal_captions(cats, xs, dists, cam.width)
    record: dict[str, list[str]] = {}
    for o, m, oc in zip(objs, masks, ords):
        caps = P.cfg["captions"]
        if caps["colour"]:
            word = colour_of(frame.rgb, m, o.category)
            if word:
                o.attributes["color"] = word
        if caps.get("material"):
            mat = material_of(P, content, frame.rgb, o.bbox2d, o.category)
            if mat:
                o.attributes["material"] = mat
        if caps.get("vlm"):
            o.description = description_of(P, content, frame.rgb, o.bbox2d, o.category)
            o.provenance["description"] = f"vlm:{P.model_meta()['vlm']['model']}"
        hc = hierarchical(o.category, o.attributes, oc, cats.count(o.category) == 1)
        o.provenance["captions"] = hc
        record[str(o.id)] = hc
    frame.meta["captions"] = record


def attributes_from_views(rgbs: list[np.ndarray], masks: list[np.ndarray]) -> dict[str, Any]:
    """A fused scan object's colour: the namer on its largest view's pixels."""
    if not masks:
        return {}
    k = int(np.argmax([m.sum() for m in masks]))
    word = colour_of(rgbs[k], masks[k])
    return {"color": word} if word else {}
