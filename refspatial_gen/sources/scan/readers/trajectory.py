"""RGB-D trajectories in the Open3D/Redwood, TUM and ICL-NUIM conventions, and loose colour/depth pairs.

Layouts (a sequence is the input folder itself or each sub-folder that matches one):
  * Redwood/Open3D/ICL-NUIM: `color/` + `depth/` (mm), optional `camera*.json` (Open3D
    PinholeCameraIntrinsic, column-major) and `trajectory.log` (camera-to-world 4x4 per frame).
  * TUM: `rgb.txt`, `depth.txt`, `groundtruth.txt` (timestamp tx ty tz qx qy qz qw), depth / 5000.
  * Pairs: `<name>_color.*` with `<name>_depth.png` (e.g. Open3D's TUM and SUN samples); no pose, so the
    world is the camera frame.
Depth encoding "auto": TUM layout or "tum" in the file name -> /5000; a SUN raw file (`sun` in the name,
no `_mm`) -> SUN's 3-bit circular shift; otherwise mm. Intrinsics: camera json, else the recipe's
`intrinsics`, else the PrimeSense default Open3D uses (525, 525, 319.5, 239.5).
No boxes ship with these datasets: objects come from `boxes.json` in the sequence folder (or the recipe's
`boxes_file`), in the trajectory's world frame. Without one, frames have no objects, so only
camera-frame questions about points and depth can be asked of them.
Gravity: the floor plane fitted over the sequence's points (gravity_source "floor_plane"), or unknown.
"""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.errors import DropUnit, InputError
from refspatial_gen.sources.scan.fileio import read_depth, read_rgb
from refspatial_gen.sources.scan.readers import validate as V
from refspatial_gen.sources.scan.readers.common import camera_from_K, load_box_file, read_json
from refspatial_gen.sources.scan.readers.leveling import level_views
from refspatial_gen.sources.scan.view import ScanView

PRIMESENSE = {"width": 640, "height": 480, "fx": 525.0, "fy": 525.0, "cx": 319.5, "cy": 239.5}
# colour frames: every format the decoder reads (a .ppm sequence was once silently "0 units")
IMG = (".png", ".jpg", ".jpeg", ".ppm", ".pgm", ".pnm", ".bmp", ".tif", ".tiff", ".webp")


def _layout(d: Path) -> str | None:
    if (d / "color").is_dir() and (d / "depth").is_dir():
        return "redwood"
    if (d / "rgb.txt").is_file() and (d / "depth.txt").is_file():
        return "tum"
    if d.is_dir() and any(p.suffix.lower() in IMG and "_color" in p.stem.lower() for p in d.iterdir()):
        return "pairs"
    return None


def _quat_pose(t, q) -> np.ndarray:
    x, y, z, w = q
    n = np.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    R = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def read_redwood_log(path: Path) -> list[np.ndarray]:
    """Redwood .log: per pose a header line then 4 rows of a camera-to-world matrix (DropUnit if malformed)."""
    try:
        rows = [ln.split() for ln in Path(path).read_text(encoding="utf-8").splitlines() if ln.strip()]
    except (OSError, UnicodeDecodeError) as e:
        raise DropUnit("pose_invalid", f"{Path(path).name}: cannot read ({type(e).__name__})") from None
    if len(rows) % 5:
        raise DropUnit("pose_invalid", f"{Path(path).name}: {len(rows)} lines, not a multiple of 5 (truncated?)")
    poses = []
    for i in range(0, len(rows), 5):
        if any(len(r) != 4 for r in rows[i + 1 : i + 5]):
            raise DropUnit("pose_invalid", f"{Path(path).name}: pose {i // 5} is not a 4x4 matrix")
        try:
            poses.append(V.pose([[float(x) for x in r] for r in rows[i + 1 : i + 5]], f"pose {i // 5}"))
        except ValueError:
            raise DropUnit("pose_invalid", f"{Path(path).name}: pose {i // 5} holds a non-number") from None
    return poses


def _tum_list(path: Path, min_fields: int = 2) -> list[tuple[float, list[str]]]:
    """A TUM list (timestamp + fields per line). rgb.txt and depth.txt list the views: InputError if malformed."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(str(path), f"cannot read ({type(e).__name__})") from None
    out = []
    for n, ln in enumerate(text.splitlines(), 1):
        if ln.strip() and not ln.startswith("#"):
            p = ln.split()
            try:
                ts = float(p[0])
            except ValueError:
                ts = float("nan")
            if len(p) < min_fields or not np.isfinite(ts):
                raise InputError(f"{path}:{n}", f"expected 'timestamp{' value' * (min_fields - 1)}', got {ln[:60]!r}")
            out.append((ts, p[1:]))
    return out


def _tum_poses(path: Path) -> list[tuple[float, list[str]]] | DropUnit:
    """groundtruth.txt (timestamp tx ty tz qx qy qz qw); malformed -> a DropUnit for every frame to raise."""
    try:
        gt = _tum_list(path, 8)
        for _, g in gt:
            [float(x) for x in g[:7]]
        return gt
    except (InputError, ValueError) as e:
        return DropUnit("pose_invalid", f"{path.name}: {e}")


def _camera_json(path: Path) -> dict[str, Any]:
    """An Open3D PinholeCameraIntrinsic json (column-major K) -> intrinsics dict; DropUnit if malformed."""
    try:
        c = V.mapping(read_json(path), path.name, "intrinsics_invalid")
    except DropUnit as e:
        raise DropUnit("intrinsics_invalid", e.detail) from None
    K = V.matrix(c.get("intrinsic_matrix"), ((3, 3),), f"{path.name} intrinsic_matrix", "intrinsics_invalid").T
    return {
        "width": V.positive_int(c.get("width"), f"{path.name} width", "intrinsics_invalid"),
        "height": V.positive_int(c.get("height"), f"{path.name} height", "intrinsics_invalid"),
        "fx": K[0, 0],
        "fy": K[1, 1],
        "cx": K[0, 2],
        "cy": K[1, 2],
    }


def _intrinsics(it: Any) -> tuple[np.ndarray, int, int]:
    """The sequence's intrinsics (camera json, the recipe's `intrinsics`, or PrimeSense) -> K, width, height."""
    it = V.mapping(it, "intrinsics", "intrinsics_invalid")
    num = {k: V.number(it.get(k), f"intrinsics {k}", "intrinsics_invalid") for k in ("fx", "fy", "cx", "cy")}
    K = np.array([[num["fx"], 0, num["cx"]], [0, num["fy"], num["cy"]], [0, 0, 1.0]])
    return (
        K,
        V.positive_int(it.get("width"), "intrinsics width", "intrinsics_invalid"),
        V.positive_int(it.get("height"), "intrinsics height", "intrinsics_invalid"),
    )


def _nearest(ts: float, items: list[tuple[float, list[str]]], max_dt: float) -> list[str] | None:
    if not items:
        return None
    k = int(np.argmin([abs(t - ts) for t, _ in items]))
    return items[k][1] if abs(items[k][0] - ts) <= max_dt else None


@lru_cache(maxsize=16)
def _sequence(seq_dir: str, encoding: str, intr_json: str) -> dict[str, Any]:
    """Frame list of one sequence: id -> (image, depth, pose or None), intrinsics, depth encoding."""
    d = Path(seq_dir)
    layout = _layout(d)
    frames: dict[str, dict[str, Any]] = {}
    intr, intr_src = dict(PRIMESENSE), "primesense_default"
    if intr_json:
        intr, intr_src = json.loads(intr_json), "recipe"
    cams = sorted(d.glob("camera*.json"))
    problem: DropUnit | None = None  # a malformed camera or pose file: every frame of the sequence drops
    if cams:
        intr_src = cams[0].name
        try:
            intr = _camera_json(cams[0])  # Open3D stores K column-major
        except DropUnit as e:
            problem = e
    enc = encoding
    if layout == "redwood":
        colors = sorted(p for p in (d / "color").iterdir() if p.suffix.lower() in IMG)
        depths = {p.stem: p for p in (d / "depth").iterdir() if p.suffix.lower() in (".png", ".npy")}
        poses = None
        if (d / "trajectory.log").is_file():
            try:
                poses = read_redwood_log(d / "trajectory.log")
            except DropUnit as e:
                problem = problem or e
        for k, c in enumerate(colors):
            pose = None if poses is None else (poses[k] if k < len(poses) else "missing")
            frames[c.stem] = {"image": c, "depth": depths.get(c.stem), "pose": pose}
        if enc == "auto":
            enc = "mm"
    elif layout == "tum":
        rgb = _tum_list(d / "rgb.txt")
        dep = _tum_list(d / "depth.txt")
        gt = _tum_poses(d / "groundtruth.txt") if (d / "groundtruth.txt").is_file() else None
        if isinstance(gt, DropUnit):
            problem, gt = problem or gt, None
        for ts, (name, *_) in rgb:
            dd = _nearest(ts, dep, 0.02)
            pose: Any = None
            if gt is not None:
                g = _nearest(ts, gt, 0.02)
                pose = "missing" if g is None else _quat_pose([float(x) for x in g[:3]], [float(x) for x in g[3:7]])
            frames[f"{ts:.6f}"] = {"image": name, "depth": None if dd is None else dd[0], "pose": pose, "rel": True}
        if enc == "auto":
            enc = "tum5000"
    elif layout == "pairs":
        for c in sorted(p for p in d.iterdir() if p.suffix.lower() in IMG and "_color" in p.stem.lower()):
            stem = c.stem[: c.stem.lower().index("_color")]
            cands = sorted(
                p for p in d.iterdir() if p.stem.lower().startswith(stem.lower() + "_depth") and p.suffix == ".png"
            )
            raw = [p for p in cands if "_mm" not in p.stem.lower()]
            dp = (raw or cands or [None])[0]
            e = enc
            if enc == "auto" and dp is not None:
                n = dp.stem.lower()
                e = "tum5000" if "tum" in n else ("sun_shift" if "sun" in n and "_mm" not in n else "mm")
            frames[stem] = {"image": c, "depth": dp, "pose": None, "encoding": e}
    for f in frames.values():
        f.setdefault("encoding", enc)
    return {"layout": layout, "frames": frames, "intrinsics": intr, "intrinsics_source": intr_src, "problem": problem}


class TrajectoryReader:
    name = "rgbd_trajectory"

    def _sequences(self, root: Path) -> list[str]:
        root = Path(root)
        if _layout(root):
            return ["."]
        return sorted(c.name for c in root.iterdir() if c.is_dir() and _layout(c))

    def detect(self, root: Path) -> bool:
        return Path(root).is_dir() and bool(self._sequences(root))

    def _seq(self, root: Path, seq: str, config: dict[str, Any]) -> dict[str, Any]:
        intr = config.get("intrinsics")
        return _sequence(
            str((Path(root) / seq).resolve()),
            str(config.get("depth_encoding") or "auto"),
            json.dumps(intr, sort_keys=True) if intr else "",
        )

    def views(self, root: Path, config: dict[str, Any]) -> list[str]:
        return [f"{s}/{fid}" for s in self._sequences(root) for fid in sorted(self._seq(root, s, config)["frames"])]

    def read(self, root: Path, view_id: str, config: dict[str, Any]) -> ScanView:
        seq, fid = view_id.rsplit("/", 1)
        info = self._seq(root, seq, config)
        f = info["frames"].get(fid)
        if f is None:
            raise DropUnit("frame_missing", f"{view_id}")
        if info["problem"] is not None:
            raise DropUnit(info["problem"].reason, f"{view_id}: {info['problem'].detail}")
        if isinstance(f["pose"], str):
            raise DropUnit("pose_missing", f"{view_id}: no trajectory entry for this frame")
        if f["depth"] is None:
            raise DropUnit("depth_missing", f"{view_id}: no depth frame")
        seq_dir = (Path(root) / seq).resolve()
        rgb = read_rgb(_frame_file(seq_dir, f, "image"))
        depth = read_depth(_frame_file(seq_dir, f, "depth"), f["encoding"])
        K, W, H = _intrinsics(info["intrinsics"])
        pose = np.eye(4) if f["pose"] is None else f["pose"]
        cam = camera_from_K(K, W, H, pose, "center", gravity_known=False)
        box_file = config.get("boxes_file") or (seq_dir / "boxes.json" if (seq_dir / "boxes.json").is_file() else None)
        boxes = load_box_file(Path(box_file)) if box_file else []
        pmeta: dict[str, Any] = {}
        if not boxes and config.get("perception"):  # no box file: objects from local models (docs/perception.md)
            from refspatial_gen.perception.scan import fused_boxes

            boxes, pmeta = fused_boxes(type(self), root, seq, view_id, f["pose"] is not None, config)
        scene = seq_dir.name
        view = ScanView(
            "rgbd_trajectory",
            scene,
            view_id if seq != "." else fid,
            rgb,
            depth,
            cam,
            boxes,
            "unknown",
            boxes_per_frame=False,
            meta={
                "intrinsics_source": info["intrinsics_source"],
                "depth_encoding": f["encoding"],
                "pose_source": "identity" if f["pose"] is None else "trajectory",
                "layout": info["layout"],
                "has_boxes": bool(boxes),
                **pmeta,
            },
        )
        frames_key = (str(seq_dir), json.dumps(sorted(info["frames"]))) if f["pose"] is not None else None
        return level_views(view, None, lambda: _scene_points(self, str(root), seq, fid, config, frames_key))


def _frame_file(seq_dir: Path, f: dict[str, Any], key: str) -> Path:
    """A frame's file; names read from a TUM list must stay inside the sequence folder."""
    return V.file_in(seq_dir, f[key], key) if f.get("rel") else f[key]


def _scene_points(
    reader: TrajectoryReader, root: str, seq: str, fid: str, config: dict[str, Any], frames_key
) -> tuple[np.ndarray, np.ndarray]:
    """Points for the floor fit: the whole posed sequence (cached), or just this frame when unposed."""
    if frames_key is not None:
        return _posed_points(reader, root, seq, json.dumps(config, sort_keys=True, default=str))
    return _points_of(reader, root, seq, [fid], config)


@lru_cache(maxsize=16)
def _posed_points(reader: TrajectoryReader, root: str, seq: str, config_json: str) -> tuple[np.ndarray, np.ndarray]:
    config = json.loads(config_json)
    info = reader._seq(Path(root), seq, config)
    return _points_of(reader, root, seq, sorted(info["frames"]), config)


def _points_of(reader: TrajectoryReader, root: str, seq: str, fids: list[str], config: dict[str, Any]):
    info = reader._seq(Path(root), seq, config)
    K, W, H = _intrinsics(info["intrinsics"])
    seq_dir = (Path(root) / seq).resolve()
    pts, ups = [], []
    for fid in fids:
        f = info["frames"][fid]
        if isinstance(f["pose"], str) or f["depth"] is None:
            continue
        try:
            d = read_depth(_frame_file(seq_dir, f, "depth"), f["encoding"])
        except DropUnit:
            continue
        if d.shape != (H, W) or not np.all(np.isfinite(d)):
            continue
        cam = camera_from_K(K, W, H, np.eye(4) if f["pose"] is None else f["pose"], "center")
        pts.append(cam.depth_to_points(d, stride=8))
        ups.append(cam.world_from_cam[:3, :3] @ np.array([0.0, -1.0, 0.0]))
    if not pts:
        return np.zeros((0, 3)), np.array([0.0, 0.0, 1.0])
    return np.concatenate(pts), np.mean(ups, axis=0)
