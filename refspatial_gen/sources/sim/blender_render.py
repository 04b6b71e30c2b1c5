"""The photoreal renderer (`renderer: blender`): Blender Cycles draws the settled scene's description.

Each generator process keeps one Blender worker process (blender_worker.py, in the Blender
environment of `make setup-blender`) and sends it each scene as a saved `RenderScene`. The frame gets
Blender's RGB, and MuJoCo's depth and instance masks: MuJoCo rasterises the physics model's own visual
geometry at pixel centres, so every label is the one a `renderer: mujoco` run gives for the same unit
(only the pixels change). Blender's own depth and object-index passes, also taken at pixel centres,
are compared with MuJoCo's per frame (render_check.py); when they disagree beyond the recipe's
thresholds the photo would not match its labels and the unit is dropped (`renderer_disagree`).
"""

from __future__ import annotations

import atexit
import json
import os
import select
import shutil
import subprocess
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.camera import Camera
from refspatial_gen.core.errors import DropUnit
from refspatial_gen.schema import Field
from refspatial_gen.sources.sim.render import RenderOut, render_views

ROOT = Path(__file__).resolve().parents[3]
WORKER = Path(__file__).resolve().parent / "blender_worker.py"
BPY_VERSION = "5.0.1"  # pinned in requirements-blender.txt

SETTINGS: dict[str, Field] = {
    "device": Field(
        str,
        default="cpu",
        choices=("cpu", "cuda", "optix", "auto"),
        doc="Cycles device; auto = the best GPU backend found, else CPU (GPU paths untested on CPU-only machines)",
    ),
    "samples": Field(
        int, default=16, min=1, max=65536, doc="path-tracing samples per pixel (fixed: no adaptive sampling)"
    ),
    "denoiser": Field(
        str, default="oidn", choices=("oidn", "optix", "none"), doc="OpenImageDenoise, OptiX (NVIDIA GPU) or none"
    ),
    "light_bounces": Field(int, default=4, min=0, max=64, doc="Cycles max bounces (diffuse/glossy capped by it)"),
    "threads": Field(int, default=0, min=0, max=1024, doc="Cycles CPU threads; 0 = all cores (same bytes either way)"),
    "seed": Field(int, default=0, min=0, max=2**31 - 1, doc="Cycles sampling seed (fixed: same scene, same bytes)"),
    "view_transform": Field(
        str,
        default="Khronos PBR Neutral",
        choices=("AgX", "Standard", "Filmic", "Khronos PBR Neutral"),
        doc="Blender colour management view transform",
    ),
    "exposure": Field(float, default=0.0, min=-10, max=10, doc="exposure in stops"),
    "light_gain": Field(
        float, default=1.0, min=0, max=100, doc="multiplies every light's power (after RefSpatial's 0.6-1.4x)"
    ),
    "ambient_gain": Field(
        float, default=1.0, min=0, max=100, doc="multiplies the grey world light (MuJoCo's ambient level)"
    ),
    "min_mask_iou": Field(
        float, default=0.9, min=0, max=1, doc="drop when an object's Blender/MuJoCo mask IoU is lower"
    ),
    "min_depth_agree": Field(float, default=0.97, min=0, max=1, doc="drop when fewer pixels' depths agree"),
    "depth_tol": Field(float, default=0.01, min=0, doc="metres: depths agree within depth_tol + depth_rel_tol * z"),
    "depth_rel_tol": Field(float, default=0.01, min=0),
    "min_pixels": Field(int, default=50, min=1, doc="objects smaller than this in both renders are not IoU-checked"),
    "timeout_s": Field(
        float, default=1800.0, min=1, doc="seconds per scene before the worker is killed and the unit dropped"
    ),
    "python": Field(
        str, default="", doc="the Blender environment's python (default $REFSPATIAL_BLENDER_PYTHON or .venv-blender)"
    ),
}
_WORKER_KEYS = (
    "device",
    "samples",
    "denoiser",
    "light_bounces",
    "threads",
    "seed",
    "view_transform",
    "exposure",
    "light_gain",
    "ambient_gain",
)


def settings(config: dict[str, Any] | None) -> dict[str, Any]:
    s = {k: f.default for k, f in SETTINGS.items()}
    s.update({k: v for k, v in ((config or {}).get("blender") or {}).items() if v is not None})
    return s


def blender_python(s: dict[str, Any]) -> Path:
    p = s.get("python") or os.environ.get("REFSPATIAL_BLENDER_PYTHON") or str(ROOT / ".venv-blender" / "bin" / "python")
    return Path(p)


def missing_reason(s: dict[str, Any]) -> str | None:
    """Why Blender cannot be used (None when its environment has bpy); cheap: does not import bpy."""
    py = blender_python(s)
    if not py.exists():
        return (
            f"the Blender environment {py} is missing: run `make setup-blender` (bpy=={BPY_VERSION}, ~0.4 GB download)"
        )
    r = subprocess.run(
        [str(py), "-I", "-c", "import importlib.util as u; print(u.find_spec('bpy') is not None)"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    if r.stdout.strip() != "True":
        return f"{py} has no bpy: run `make setup-blender`"
    return None


class BlenderWorker:
    """One Blender process fed JSON requests on stdin; replies on its stdout, its prints in a log file."""

    def __init__(self, python: Path) -> None:
        self.tmp = Path(tempfile.mkdtemp(prefix="refspatial-blender-"))
        self.log = self.tmp / "worker.log"
        env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
        with open(self.log, "wb") as err:
            self.proc = subprocess.Popen(
                [str(python), "-I", str(WORKER), "--serve"],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=err,
                env=env,
                cwd=self.tmp,
            )

    def request(self, req: dict[str, Any], timeout: float) -> dict[str, Any]:
        req = {**req, "log": str(self.log)}
        try:
            self.proc.stdin.write((json.dumps(req) + "\n").encode())
            self.proc.stdin.flush()
        except OSError as e:  # the worker is gone (crashed between two scenes)
            tail = self.log_tail()
            self.close(kill=True)
            raise DropUnit("render_failed", f"the Blender worker is gone ({e}): {tail}") from None
        ready, _, _ = select.select([self.proc.stdout], [], [], timeout)
        if not ready:
            self.close(kill=True)
            raise DropUnit("render_timeout", f"Blender took longer than {timeout:.0f} s")
        line = self.proc.stdout.readline()
        if not line:
            tail = self.log_tail()
            self.close()
            raise DropUnit("render_failed", f"the Blender worker exited (code {self.proc.poll()}): {tail}")
        return json.loads(line)

    def log_tail(self, n: int = 600) -> str:
        try:
            return self.log.read_text(errors="replace")[-n:].strip()
        except OSError:
            return ""

    def alive(self) -> bool:
        return self.proc.poll() is None

    def close(self, kill: bool = False) -> None:
        """End the worker: closing its stdin ends its loop; `kill` (or a worker that does not end) kills it."""
        if self.proc.poll() is None:
            try:
                if kill:
                    raise subprocess.TimeoutExpired("blender", 0)
                self.proc.stdin.close()
                self.proc.wait(timeout=10)
            except (OSError, subprocess.TimeoutExpired):
                self.proc.kill()
                self.proc.wait()
        shutil.rmtree(self.tmp, ignore_errors=True)


_POOL: dict[tuple[int, str], BlenderWorker] = {}
TIMES: dict[str, float] = {}  # seconds inside the worker by stage (build, rgb, passes), summed: for `make bench`


def worker(python: Path) -> BlenderWorker:
    """This process's worker (a forked child starts its own: the key holds the pid)."""
    key = (os.getpid(), str(python))
    w = _POOL.get(key)
    if w is None or not w.alive():
        if w is not None:
            w.close()
        w = _POOL[key] = BlenderWorker(python)
    return w


@atexit.register
def _close_all() -> None:
    for key, w in list(_POOL.items()):
        if key[0] == os.getpid():
            w.close()
        _POOL.pop(key, None)


@dataclass
class BlenderOut(RenderOut):
    """Blender's RGB with MuJoCo's depth and ids; `blender_depth` / `blender_ids` are Blender's own passes."""

    blender_depth: np.ndarray | None = None
    blender_ids: np.ndarray | None = None
    meta: dict[str, Any] = field(default_factory=dict)


def render_blender(scene, cams: list[Camera], s: dict[str, Any]) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(rgb, depth, ids) per camera from the Blender worker."""
    from PIL import Image

    w = worker(blender_python(s))
    req_dir = w.tmp / "req"
    shutil.rmtree(req_dir, ignore_errors=True)
    scene.describe(cams).save(req_dir / "scene")
    reply = w.request(
        {
            "op": "render",
            "scene": str(req_dir / "scene"),
            "out": str(req_dir / "out"),
            "settings": {k: s[k] for k in _WORKER_KEYS},
        },
        float(s["timeout_s"]),
    )
    if not reply.get("ok"):
        raise DropUnit("render_failed", reply.get("error", "Blender failed"))
    for k, v in reply.get("seconds", {}).items():
        TIMES[k] = TIMES.get(k, 0.0) + float(v)
    out = []
    for v in range(len(cams)):
        with Image.open(req_dir / "out" / f"v{v}_rgb.png") as im:
            rgb = np.asarray(im.convert("RGB"))
        out.append((rgb, np.load(req_dir / "out" / f"v{v}_depth.npy"), np.load(req_dir / "out" / f"v{v}_index.npy")))
    shutil.rmtree(req_dir, ignore_errors=True)
    return out


class BlenderRenderer:
    """Cycles (CPU, CUDA or OptiX) with OpenImageDenoise; geometry checked against MuJoCo per frame."""

    name = "blender"

    def __init__(self, config: dict[str, Any] | None = None) -> None:
        self.settings = settings(config)

    def render(self, scene, cams: list[Camera]) -> list[BlenderOut]:
        from refspatial_gen.sources.sim.render_check import agreement, disagreement

        if not cams:
            return []
        s = self.settings
        ref = render_views(scene.sim, cams)
        outs = []
        for v, (r, (rgb, depth, ids)) in enumerate(zip(ref, render_blender(scene, cams, s))):
            stats = agreement(
                r.depth,
                r.instance,
                depth,
                ids,
                min_pixels=int(s["min_pixels"]),
                depth_tol=float(s["depth_tol"]),
                depth_rel_tol=float(s["depth_rel_tol"]),
            )
            why = disagreement(stats, float(s["min_mask_iou"]), float(s["min_depth_agree"]))
            if why:
                raise DropUnit("renderer_disagree", f"view {v}: Blender and MuJoCo disagree: {why}")
            check = {k: stats[k] for k in ("mask_iou_mean", "mask_iou_min", "depth_agree")}
            outs.append(
                BlenderOut(rgb, r.depth, r.instance, depth, ids, {"renderer": "blender", "render_check": check})
            )
        return outs
