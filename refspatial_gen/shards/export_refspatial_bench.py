"""`export --format refspatial-bench`: the raw layout of RefSpatial-Bench, so RoboRefer's own evaluation
scripts (`Evaluation/test_benchmark.py`, `Evaluation/summarize_acc.py`) run on it unchanged.

OUT/
  Location/  image/<id>.png  mask/<id>.png  question.json
  Placement/ ...
  Unseen/    ...

question.json is a JSON list of {id, object, prompt, suffix, rgb_path, mask_path, category, step} (the
benchmark's fields; `qa_id` is added so results can be traced back). `id` counts from 0 in each folder;
`prompt` is the question without its output-format sentence; `suffix` is RoboRefer's output-format
instruction (a list of tuples of normalised coordinates); `object` is the target's description taken from
the prompt; `category` is "location" or "placement"; `step` is the QA pair's step count. Images are RGB
PNG; masks are 8-bit single-channel PNG, 255 on the target's visible mask (Location) or on the free-space
region's visible pixels (Placement), 0 elsewhere, the image's size.

Which QA pairs: point answers (locate, identify) go to Location, free-space answers (placement) to
Placement, from the requested splits (default: test); QA pairs of the `unseen` split go to Unseen. Every
item is checked the benchmark's way before it is written: the gold point, read as RoboRefer's script reads
it (`int(x * W)`, `int(y * H)`), must fall inside the mask. Files are numbered per folder (no sample id
in a name, so ids never collide) and created once (export_files.write_new); `check_export` compares every
image with the stored view of its QA pair, and `shards.export` writes the whole folder atomically.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from refspatial_gen.core.mask import RLE
from refspatial_gen.rewards.gold import build_gold
from refspatial_gen.run.splits import keep_sample, sample_split, splits_of_samples
from refspatial_gen.shards.export_files import write_new
from refspatial_gen.shards.format import RawSample

SUFFIX = (
    "Your answer should be formatted as a list of tuples, i.e. [(x1, y1)], where each tuple contains the x and "
    "y coordinates of a point satisfying the conditions above. The coordinates should be between 0 and 1, "
    "indicating the normalized pixel locations of the points in the image."
)
TASKS = {"points": ("Location", "location"), "region": ("Placement", "placement")}
TASKS_FOLDERS = ("Location", "Placement", "Unseen")
_LEAD = re.compile(
    r"^(?:please\s+)?(?:point\s+(?:out|to|at)|locate|find|show\s+me|identify|mark)\s+(?P<obj>.+?)[.?!]?$", re.I
)
_WHERE = re.compile(r"^where\s+is\s+(?P<obj>.+?)\?$", re.I)


def point_instructions() -> list[str]:
    """The output-format sentences the templates append to point questions (qa.lexicon), unescaped."""
    from refspatial_gen.qa import lexicon

    return [s.replace("\\[", "[").replace("\\]", "]") for s in lexicon.POINT_INSTRUCTIONS]


def split_prompt(question: str) -> tuple[str, bool]:
    """(question without its trailing output-format sentence, whether one was found). Whitespace is
    ignored in the comparison: the text tidy step may drop a space before punctuation."""
    q = question.strip()
    keep = [i for i, c in enumerate(q) if not c.isspace()]
    dense = "".join(q[i] for i in keep)
    for s in point_instructions():
        tail = re.sub(r"\s+", "", s)
        if tail and dense.endswith(tail):
            return q[: keep[len(dense) - len(tail)]].strip(), True
    return q, False


def object_of(prompt: str, qa: dict) -> str:
    """The target's description: the object of the prompt's imperative ("Point to X." -> X), else for
    free space the key step naming it, else the prompt without a trailing "Point to it."."""
    for rx in (_LEAD, _WHERE):
        m = rx.match(prompt)
        if m and not re.search(r"[.?!]\s+[A-Z]", m.group("obj")):  # one sentence ("1. left of" is fine)
            return m.group("obj").strip()
    if (qa.get("answer_struct") or {}).get("kind") == "region":
        for k in reversed(qa.get("key_steps") or []):
            if k["phrase"].startswith("the free space"):
                return k["phrase"]
    return re.sub(r"\s*Point to it\.$", "", prompt).strip()


def benchmark_hit(point: list[float], mask: np.ndarray) -> bool:
    """RoboRefer's summarize_acc rule for one normalised point: int(x*W), int(y*H) inside the mask."""
    H, W = mask.shape
    x, y = int(point[0] * W), int(point[1] * H)
    return 0 <= x < W and 0 <= y < H and bool(mask[y, x])


def _png(arr: np.ndarray) -> bytes:
    import cv2

    ok, buf = cv2.imencode(".png", arr, [cv2.IMWRITE_PNG_COMPRESSION, 3])
    if not ok:
        raise ValueError("PNG encoding failed")
    return buf.tobytes()


def export_refspatial_bench(
    raws: Iterable[RawSample], out: Path | str, *, splits: Iterable[str] | None = ("test",)
) -> dict:
    """Write the three task folders; returns counts per task and how many prompts had no known format sentence."""
    out = Path(out)
    scene_map = splits_of_samples(raws)
    wanted = None if splits is None else tuple(splits)
    items: dict[str, list[dict]] = {"Location": [], "Placement": [], "Unseen": []}
    no_instruction = 0
    for raw in raws:
        h = raw.header
        frame_ids = list(h["frame_ids"])
        metas = [raw.frame_meta(v) for v in range(int(h["views"]))]
        split = sample_split(scene_map, metas, h["sample_id"])
        unseen = split == "unseen"
        if not unseen and not keep_sample(split, wanted):
            continue
        graphs = {g["frame_id"]: g for g in raw.graphs_json()}
        cache: dict[int, tuple[np.ndarray, np.ndarray | None]] = {}
        for qa in raw.qa_json():
            kind = (qa.get("answer_struct") or {}).get("kind")
            if kind not in TASKS or len(qa["frame_ids"]) != 1 or qa["frame_ids"][0] not in frame_ids:
                continue
            v = frame_ids.index(qa["frame_ids"][0])
            if v not in cache:
                cache[v] = (
                    raw.rgb(v),
                    raw.depth(v)
                    if any((q.get("answer_struct") or {}).get("kind") == "region" for q in raw.qa_json())
                    else None,
                )
            rgb, depth = cache[v]
            gold = build_gold(qa, metas[v], graphs.get(metas[v]["frame_id"]), depth)
            mask = RLE.from_json(gold.mask).decode()
            if not benchmark_hit(gold.points[0], mask):
                raise ValueError(
                    f"{qa['qa_id']}: the gold point {gold.points[0]} misses its own mask the benchmark's way"
                )
            folder, category = ("Unseen", TASKS[kind][1]) if unseen else TASKS[kind]
            prompt, found = split_prompt(qa["question"])
            no_instruction += not found
            i = len(items[folder])
            d = out / folder
            (d / "image").mkdir(parents=True, exist_ok=True)
            (d / "mask").mkdir(parents=True, exist_ok=True)
            write_new(d / "image" / f"{i}.png", _png(np.ascontiguousarray(rgb[..., ::-1])))
            write_new(d / "mask" / f"{i}.png", _png(mask.astype(np.uint8) * 255))
            items[folder].append(
                {
                    "id": i,
                    "object": object_of(prompt, qa),
                    "prompt": prompt,
                    "suffix": SUFFIX,
                    "rgb_path": f"image/{i}.png",
                    "mask_path": f"mask/{i}.png",
                    "category": category,
                    "step": int(qa["steps"]),
                    "qa_id": qa["qa_id"],
                }
            )
    for folder, rows in items.items():
        if rows:
            write_new(out / folder / "question.json", json.dumps(rows, ensure_ascii=False, indent=1).encode())
    return {**{k.lower(): len(v) for k, v in items.items()}, "prompts_without_format_sentence": no_instruction}


def check_export(out: Path, raws: Iterable[RawSample]) -> list[str]:
    """Every item's image is its QA pair's stored view, pixel for pixel, and its mask a non-empty 8-bit
    single-channel PNG of the image's size; ids count from 0; nothing else lies in image/ or mask/."""
    import cv2

    out = Path(out)
    rows: dict[str, tuple[str, dict]] = {}
    problems: list[str] = []
    for folder in TASKS_FOLDERS:
        q = out / folder / "question.json"
        if not q.is_file():
            continue
        try:
            items = json.loads(q.read_text(encoding="utf-8"))
            named = {(r["rgb_path"], r["mask_path"]) for r in items}
            ids = [r["id"] for r in items]
            rows.update({r["qa_id"]: (folder, r) for r in items})
        except (ValueError, KeyError, TypeError) as e:
            problems.append(f"{q}: not a benchmark question list ({e})")
            continue
        if ids != list(range(len(items))):
            problems.append(f"{q}: ids are not 0..{len(items) - 1}")
        files = {f"{sub}/{p.name}" for sub in ("image", "mask") for p in (out / folder / sub).iterdir()}
        if files != {p for pair in named for p in pair}:
            problems.append(f"{out / folder}: image/mask files do not match question.json")
    for raw in raws:
        frame_ids = list(raw.header["frame_ids"])
        for qa in raw.qa_json():
            if qa["qa_id"] not in rows:
                continue
            folder, r = rows.pop(qa["qa_id"])
            where = f"{out / folder / 'question.json'}: item {r['id']}"
            img = cv2.imread(str(out / folder / r["rgb_path"]), cv2.IMREAD_UNCHANGED)
            mask = cv2.imread(str(out / folder / r["mask_path"]), cv2.IMREAD_UNCHANGED)
            rgb = raw.rgb(frame_ids.index(qa["frame_ids"][0]))
            if img is None or img.shape != rgb.shape or not np.array_equal(img[..., ::-1], rgb):
                problems.append(f"{where}: image is not the stored view of {qa['qa_id']}")
            elif mask is None or mask.dtype != np.uint8 or mask.shape != rgb.shape[:2] or not mask.any():
                problems.append(f"{where}: mask is not a non-empty 8-bit single-channel image of the image's size")
    problems += [
        f"{out / f}: item {r['id']} names QA pair {q!r}, which is not in the shards" for q, (f, r) in rows.items()
    ]
    return problems
