"""COLMAP reconstructions through pycolmap: poses and intrinsics from a model, or SfM on a folder of images.

Folder layout: `images/` plus a model in `sparse/0/`, `sparse/` or the folder itself (cameras, images,
points3D as .bin or .txt). Optional: `depth/<image stem>.png|.npy` (a sensor's depth, mm or metres);
without it depth is splatted from the model's 3D points (sparse: few pixels get depth).
`boxes.json` (generic schema) gives objects in the model's world frame.
COLMAP's world has arbitrary scale and orientation. `reference_poses.json` ({image name: world_from_cam
4x4}, e.g. from a simulator or a motion-capture system) aligns it by a similarity fitted on camera
centres; `options.up` gives the up vector; otherwise the floor plane is fitted on the 3D points.
COLMAP's pixel convention is corner-origin, the same as Camera's, so K is used as is. Lens distortion
parameters are ignored (recorded in meta): undistort images first (COLMAP image_undistorter) for
wide-angle lenses.
"""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.sources.scan.fileio import read_depth, read_rgb
from refspatial_gen.sources.scan.readers.common import camera_from_K, load_box_file
from refspatial_gen.sources.scan.readers.leveling import apply_world_transform, level_views
from refspatial_gen.sources.scan.view import ScanView

MODEL_FILES = ("cameras.bin", "cameras.txt")


def model_dir(root: Path) -> Path | None:
    for d in (root / "sparse" / "0", root / "sparse", root):
        if any((d / f).is_file() for f in MODEL_FILES):
            return d
    return None


def umeyama(src: np.ndarray, dst: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Similarity (s, R, t) minimising |dst - (s R src + t)|^2 (Umeyama 1991)."""
    mu_s, mu_d = src.mean(0), dst.mean(0)
    xs, xd = src - mu_s, dst - mu_d
    U, S, Vt = np.linalg.svd(xd.T @ xs / len(src))
    D = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        D[2, 2] = -1
    R = U @ D @ Vt
    s = float(np.trace(np.diag(S) @ D) / xs.var(0).sum())
    return s, R, mu_d - s * R @ mu_s


def model_poses(rec) -> dict[str, np.ndarray]:
    """Registered image name -> world_from_cam (4x4) of a pycolmap Reconstruction."""
    out = {}
    for iid in sorted(rec.reg_image_ids()):
        im = rec.image(iid)
        cfw = im.cam_from_world() if callable(im.cam_from_world) else im.cam_from_world
        T = np.eye(4)
        T[:3, :4] = np.asarray(cfw.matrix())
        out[im.name] = np.linalg.inv(T)
    return out


def pose_errors(est: dict[str, np.ndarray], ref: dict[str, np.ndarray]) -> dict[str, Any]:
    """Fit a similarity on camera centres, then report centre (m) and rotation (deg) errors per image."""
    names = sorted(set(est) & set(ref))
    if len(names) < 3:
        raise ValueError(f"need 3 common images to align, have {len(names)}")
    s, R, t = umeyama(np.array([est[n][:3, 3] for n in names]), np.array([ref[n][:3, 3] for n in names]))
    cerr, rerr = [], []
    for n in names:
        c = s * R @ est[n][:3, 3] + t
        Rw = R @ est[n][:3, :3]
        cerr.append(float(np.linalg.norm(c - ref[n][:3, 3])))
        cosang = (np.trace(Rw.T @ ref[n][:3, :3]) - 1) / 2
        rerr.append(float(np.degrees(np.arccos(np.clip(cosang, -1, 1)))))
    return {
        "images": names,
        "scale": s,
        "R": R,
        "t": t,
        "centre_err_m": cerr,
        "rot_err_deg": rerr,
        "max_centre_err_m": max(cerr),
        "max_rot_err_deg": max(rerr),
    }


def run_sfm(
    image_dir: Path,
    work_dir: Path,
    camera_model: str = "PINHOLE",
    single_camera: bool = True,
    camera_params: tuple[float, ...] | None = None,
):
    """SIFT features, exhaustive matching and incremental mapping; returns the largest Reconstruction
    (written to work_dir/sparse/0). Slow: seconds per handful of images on CPU.

    `camera_params` (COLMAP order, corner-origin pixels, e.g. PINHOLE fx, fy, cx, cy) fixes a calibrated
    camera's intrinsics: they are then not refined, which removes the focal/rotation ambiguity."""
    import pycolmap

    work_dir = Path(work_dir)
    work_dir.mkdir(parents=True, exist_ok=True)
    db = work_dir / "database.db"
    if db.exists():
        db.unlink()
    reader_opts = pycolmap.ImageReaderOptions()
    reader_opts.camera_model = camera_model
    if camera_params is not None:
        reader_opts.camera_params = ",".join(f"{float(x):.10g}" for x in camera_params)
    pycolmap.extract_features(
        db,
        image_dir,
        camera_mode=pycolmap.CameraMode.SINGLE if single_camera else pycolmap.CameraMode.AUTO,
        reader_options=reader_opts,
        device=pycolmap.Device.cpu,
    )
    pycolmap.match_exhaustive(db, device=pycolmap.Device.cpu)
    out = work_dir / "sparse"
    out.mkdir(exist_ok=True)
    opts = pycolmap.IncrementalPipelineOptions()
    if camera_params is not None:
        opts.ba_refine_focal_length = False
        opts.ba_refine_principal_point = False
        opts.ba_refine_extra_params = False
    recs = pycolmap.incremental_mapping(db, image_dir, out, options=opts)
    if not recs:
        raise DropUnit("sfm_failed", f"COLMAP registered no images in {image_dir}")
    best = max(recs.values(), key=lambda r: r.num_reg_images())
    (out / "0").mkdir(exist_ok=True)
    best.write(out / "0")
    return best


@lru_cache(maxsize=4)
def _model(root_s: str) -> dict[str, Any]:
    import pycolmap

    root = Path(root_s)
    md = model_dir(root)
    if md is None:
        raise DropUnit("model_missing", f"{root}: no COLMAP model")
    rec = pycolmap.Reconstruction(str(md))
    poses = model_poses(rec)
    cams = {}
    for iid in sorted(rec.reg_image_ids()):
        im = rec.image(iid)
        cam = rec.camera(im.camera_id)
        cams[im.name] = {
            "K": np.asarray(cam.calibration_matrix()),
            "width": int(cam.width),
            "height": int(cam.height),
            "model": str(cam.model_name),
            "params": [float(x) for x in cam.params],
        }
    pts = np.array([p.xyz for _, p in sorted(rec.points3D.items())], float).reshape(-1, 3)
    S = np.eye(4)  # world <- model similarity (scale folded into points and translations)
    align = None
    ref = root / "reference_poses.json"
    if ref.is_file():
        refp = {k: np.asarray(v, float) for k, v in json.loads(ref.read_text()).items()}
        err = pose_errors(poses, refp)
        S[:3, :3], S[:3, 3] = err["scale"] * err["R"], err["t"]
        align = {
            "scale": err["scale"],
            "max_centre_err_m": err["max_centre_err_m"],
            "max_rot_err_deg": err["max_rot_err_deg"],
        }
    s = np.cbrt(np.linalg.det(S[:3, :3]))
    world_poses = {}
    for n, T in poses.items():
        W = np.eye(4)
        W[:3, :3] = S[:3, :3] @ T[:3, :3] / s
        W[:3, 3] = S[:3, :3] @ T[:3, 3] + S[:3, 3]
        world_poses[n] = W
    pts = pts @ S[:3, :3].T + S[:3, 3]
    return {"poses": world_poses, "cams": cams, "points": pts, "align": align, "model_dir": str(md)}


class ColmapReader:
    name = "colmap"

    def detect(self, root: Path) -> bool:
        return Path(root).is_dir() and model_dir(Path(root)) is not None

    def views(self, root: Path, config: dict[str, Any]) -> list[str]:
        return sorted(_model(str(Path(root).resolve()))["poses"])

    def read(self, root: Path, view_id: str, config: dict[str, Any]) -> ScanView:
        root = Path(root).resolve()
        m = _model(str(root))
        if view_id not in m["poses"]:
            raise DropUnit("pose_missing", f"{root}: image {view_id} is not registered in the model")
        opts = config.get("options") or {}
        img_dir = root / str(opts.get("images_dir", "images"))
        rgb = read_rgb(img_dir / view_id)
        c = m["cams"][view_id]
        stem = Path(view_id).stem
        depth = None
        for ext in (".png", ".npy"):
            p = root / "depth" / (stem + ext)
            if p.is_file():
                depth = read_depth(p, str(config.get("depth_encoding") or "auto").replace("auto", "mm"))
        cam = camera_from_K(c["K"], c["width"], c["height"], m["poses"][view_id], "corner", gravity_known=False)
        box_file = config.get("boxes_file") or (root / "boxes.json" if (root / "boxes.json").is_file() else None)
        boxes = load_box_file(Path(box_file)) if box_file else []
        extra = c["params"][4:] if c["model"] in ("PINHOLE", "OPENCV", "FULL_OPENCV") else c["params"][3:]
        view = ScanView(
            "colmap",
            root.name,
            stem,
            rgb,
            depth,
            cam,
            boxes,
            "unknown",
            points=None if depth is not None else m["points"],
            meta={
                "intrinsics_source": f"colmap:{c['model']}",
                "distortion_ignored": extra,
                "pose_source": "colmap",
                "alignment": m["align"],
            },
        )
        up = opts.get("up")
        if up is None and m["align"] is not None and opts.get("reference_z_up", True):
            return apply_world_transform(view, np.eye(4), "given", True)
        pts = m["points"] if depth is None else cam.depth_to_points(depth, stride=8)
        return level_views(
            view,
            None if up is None else np.asarray(up, float),
            lambda: (pts, np.mean([T[:3, :3] @ np.array([0, -1.0, 0]) for T in m["poses"].values()], axis=0)),
        )
