"""The Blender worker: a long-lived process in the Blender environment (`make setup-blender`:
`.venv-blender` with `bpy` and the numpy it was built for) that renders saved scene descriptions.

Why a separate process: `bpy` 5.0.1 requires numpy < 2 and the generator pins numpy 2.4, so they
cannot share an interpreter; a process of its own also keeps Blender's global state and memory out of
the generator and turns a Blender crash into one dropped unit. It imports only the standard library,
numpy and bpy (run it as a script, never as part of the package).

Protocol: one JSON request per line on stdin, one JSON reply per line on the reply channel (the
original stdout; Blender's own prints go to a log file):
  {"op": "probe"} -> {"ok": true, "bpy": "5.0.1", "devices": [...]}
  {"op": "render", "scene": DIR, "out": DIR, "settings": {...}} -> {"ok": true, "device": "cpu", "views": n}
For each camera v it writes `v{v}_rgb.png` (Cycles, `samples` samples, denoised) and `v{v}_depth.npy`
(float32 z-depth in metres, 0 = nothing) and `v{v}_index.npy` (int32 object pass index = instance id)
from a second 1-sample pass whose pixel filter is 0.01 px wide, so both passes sample pixel centres
(Cycles' Z and object index passes take one sample, jittered across the filter footprint).

Debugging: `python blender_worker.py --scene DIR --out DIR [--samples N]` renders one description.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import sys
import traceback
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
DENOISERS = {"oidn": "OPENIMAGEDENOISE", "optix": "OPTIX"}


def _scene_module():
    spec = importlib.util.spec_from_file_location("refspatial_blender_scene", HERE / "blender_scene.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def gpu_devices() -> list[str]:
    """Compute backends with at least one GPU device ("optix", "cuda"), best first."""
    import bpy

    prefs = bpy.context.preferences.addons["cycles"].preferences
    found = []
    for kind in ("OPTIX", "CUDA"):
        try:
            prefs.compute_device_type = kind
        except TypeError:  # backend not compiled in or not available on this machine
            continue
        prefs.get_devices()
        if any(d.type == kind for d in prefs.devices):
            found.append(kind.lower())
    return found


def select_device(device: str) -> str:
    """`cpu`, `cuda`, `optix` or `auto` (best GPU backend, else CPU). GPU paths are untested on CPU machines."""
    import bpy

    sc = bpy.context.scene
    if device == "cpu":
        sc.cycles.device = "CPU"
        return "cpu"
    avail = gpu_devices()
    kind = (avail[0] if avail else "cpu") if device == "auto" else device
    if kind == "cpu":
        sc.cycles.device = "CPU"
        return "cpu"
    if kind not in avail:
        raise RuntimeError(
            f"device {device!r} asked for, but Cycles finds no {kind.upper()} GPU (found: {avail or 'none'})"
        )
    prefs = bpy.context.preferences.addons["cycles"].preferences
    prefs.compute_device_type = kind.upper()
    prefs.get_devices()
    for d in prefs.devices:
        d.use = d.type == kind.upper()
    sc.cycles.device = "GPU"
    return kind


def configure(s: dict[str, Any]) -> str:
    """Render settings from the recipe's `blender:` section (see blender_render.SETTINGS)."""
    import bpy

    sc = bpy.context.scene
    sc.render.engine = "CYCLES"
    dev = select_device(s["device"])
    cy = sc.cycles
    cy.samples, cy.use_adaptive_sampling = int(s["samples"]), False
    cy.seed, cy.use_animated_seed = int(s["seed"]), False
    cy.max_bounces = int(s["light_bounces"])
    for k in ("diffuse_bounces", "glossy_bounces", "transmission_bounces", "volume_bounces"):
        setattr(cy, k, min(int(s["light_bounces"]), getattr(cy, k)))
    cy.use_denoising = s["denoiser"] != "none"
    if cy.use_denoising:
        cy.denoiser = DENOISERS[s["denoiser"]]
        cy.denoising_input_passes, cy.denoising_prefilter = "RGB_ALBEDO_NORMAL", "ACCURATE"
        cy.denoising_use_gpu = dev != "cpu"
    sc.render.threads_mode = "FIXED" if int(s["threads"]) > 0 else "AUTO"
    if int(s["threads"]) > 0:
        sc.render.threads = int(s["threads"])
    sc.render.dither_intensity = 0.0  # dithering adds noise to 8-bit output
    sc.render.use_persistent_data = True  # the second pass and the next views reuse the scene's BVH
    sc.view_settings.view_transform = s["view_transform"]
    sc.view_settings.look = "None"
    sc.view_settings.exposure = float(s["exposure"])
    vl = sc.view_layers[0]
    vl.use_pass_z = vl.use_pass_object_index = True
    return dev


def _data_outputs(out: Path):
    """Compositor: the Depth and Object Index passes to float EXR files (used by the data pass only)."""
    import bpy

    sc = bpy.context.scene
    ng = bpy.data.node_groups.new("passes", "CompositorNodeTree")
    sc.compositing_node_group = ng
    rl = ng.nodes.new("CompositorNodeRLayers")
    fo = ng.nodes.new("CompositorNodeOutputFile")
    fo.directory, fo.file_name = str(out) + "/", "pass_"
    fo.format.media_type = "IMAGE"  # Blender 5: the node writes one multilayer file unless told otherwise
    fo.format.file_format, fo.format.color_depth, fo.format.exr_codec = "OPEN_EXR", "32", "ZIP"
    fo.file_output_items.new("FLOAT", "depth")
    fo.file_output_items.new("FLOAT", "index")
    ng.links.new(rl.outputs["Depth"], fo.inputs["depth"])
    ng.links.new(rl.outputs["Object Index"], fo.inputs["index"])


def _read_exr(path: Path, W: int, H: int) -> np.ndarray:
    import bpy

    img = bpy.data.images.load(str(path), check_existing=False)
    px = np.empty(W * H * img.channels, np.float32)
    img.pixels.foreach_get(px)
    ch = img.channels
    bpy.data.images.remove(img)
    path.unlink()
    return px.reshape(H, W, ch)[::-1, :, 0].copy()  # Blender's first row is the bottom one


def render_scene(scene_dir: str, out_dir: str, s: dict[str, Any]) -> dict[str, Any]:
    import time

    import bpy

    t0 = time.perf_counter()
    times = {"build": 0.0, "rgb": 0.0, "passes": 0.0}
    sm = _scene_module()
    doc = sm.build(scene_dir, float(s["light_gain"]), float(s["ambient_gain"]))
    dev = configure(s)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    _data_outputs(out)
    sc, cy = bpy.context.scene, bpy.context.scene.cycles
    samples, denoise = cy.samples, cy.use_denoising
    times["build"] = time.perf_counter() - t0
    for v, cam in enumerate(doc["cameras"]):
        sm.set_camera(sc.camera, cam)
        W, H = int(cam["width"]), int(cam["height"])
        # pass 1: the photo
        cy.samples, cy.use_denoising, cy.pixel_filter_type, cy.filter_width = samples, denoise, "BLACKMAN_HARRIS", 1.5
        cy.max_bounces = int(s["light_bounces"])
        sc.render.use_compositing = False
        sc.render.image_settings.file_format, sc.render.image_settings.color_mode = "PNG", "RGB"
        sc.render.image_settings.color_depth, sc.render.image_settings.compression = "8", 15
        sc.render.filepath = str(out / f"v{v}_rgb.png")
        t1 = time.perf_counter()
        bpy.ops.render.render(write_still=True)
        t2 = time.perf_counter()
        # pass 2: depth and object index at pixel centres
        cy.samples, cy.use_denoising, cy.pixel_filter_type, cy.filter_width = 1, False, "BOX", 0.01
        cy.max_bounces = 0
        sc.render.use_compositing = True
        bpy.ops.render.render(write_still=False)
        depth = _read_exr(out / "pass_depth.exr", W, H)
        depth[~np.isfinite(depth) | (depth >= 1e9)] = 0.0
        np.save(out / f"v{v}_depth.npy", depth.astype(np.float32))
        np.save(out / f"v{v}_index.npy", np.rint(_read_exr(out / "pass_index.exr", W, H)).astype(np.int32))
        times["rgb"] += t2 - t1
        times["passes"] += time.perf_counter() - t2
    return {"device": dev, "views": len(doc["cameras"]), "seconds": {k: round(x, 3) for k, x in times.items()}}


def _log_to(path: str | None) -> None:
    """Point fds 1 and 2 (Blender's and Cycles' prints) at `path`, truncated: the log of this request only."""
    if not path:
        return
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    os.close(fd)


def serve() -> int:
    reply = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)  # anything Blender prints must never reach the reply channel
    for line in sys.stdin:
        if not line.strip():
            continue
        try:
            req = json.loads(line)
            _log_to(req.get("log"))
            if req["op"] == "probe":
                import bpy

                res = {"bpy": bpy.app.version_string, "devices": gpu_devices()}
            elif req["op"] == "render":
                res = render_scene(req["scene"], req["out"], req["settings"])
            else:
                raise ValueError(f"unknown op {req['op']!r}")
            reply.write(json.dumps({"ok": True, **res}) + "\n")
        except Exception as e:  # reported to the generator, which drops the unit with the reason
            reply.write(
                json.dumps({"ok": False, "error": f"{type(e).__name__}: {e}", "trace": traceback.format_exc()}) + "\n"
            )
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--serve", action="store_true", help="answer JSON requests on stdin (used by blender_render.py)")
    ap.add_argument("--scene", help="a folder written by `refspatial-gen sim describe`")
    ap.add_argument("--out")
    ap.add_argument("--settings", default="{}", help="JSON settings overriding the defaults below")
    args = ap.parse_args(argv)
    if args.serve:
        return serve()
    s = {
        "device": "cpu",
        "samples": 32,
        "denoiser": "oidn",
        "light_bounces": 4,
        "threads": 0,
        "seed": 0,
        "view_transform": "Khronos PBR Neutral",
        "exposure": 0.0,
        "light_gain": 1.0,
        "ambient_gain": 1.0,
    } | json.loads(args.settings)
    print(json.dumps(render_scene(args.scene, args.out, s)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
