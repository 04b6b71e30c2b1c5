"""Build a Blender scene from a saved renderer-neutral description (`RenderScene.save`: scene.json,
meshes.npz, textures/*.png). Runs inside the Blender worker process (`blender_worker.py`), never in
the generator: it imports only the standard library, numpy and `bpy`.

Why these mappings (the description is MuJoCo-flavoured; Cycles is physical):
- colours: `look.rgba` is what MuJoCo shows on screen, i.e. sRGB; Cycles wants linear base colours, so
  rgba goes through the sRGB -> linear curve (the same curve Blender applies to the PNG textures);
- materials: MuJoCo's specular / shininess / reflectance become a Principled BSDF's Specular IOR Level
  / Roughness = 1 - 0.9 * shininess / Metallic for the metal-like reflectance of the catalog (>= 0.15);
- lights: MuJoCo's diffuse level D of a light (colour x base x RefSpatial's 0.6-1.4 intensity) becomes
  the light whose direct irradiance makes a white diffuse surface facing it read D (linear): a sun of
  strength pi * D, a spot of power 4 pi^2 d^2 * D where d is the light's distance to the lit objects'
  height along its axis (Cycles' 1/d^2 falloff then matches at the objects). MuJoCo's ambient becomes
  a uniform grey world; its headlight has no physical counterpart and is left out;
- cameras: OpenCV intrinsics exactly (horizontal sensor fit, lens from fx, shift from the principal
  point, pixel aspect from fy / fx); see `set_camera`.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

SUN_ANGLE_DEG = 2.0  # soft daylight shadows
SPOT_RADIUS = 0.08  # metres: a small bulb, soft-edged shadows
SPOT_BLEND = 0.35
SMOOTH_ANGLE_DEG = 35.0  # MuJoCo also averages normals only across gentle edges


def srgb_to_linear(c) -> np.ndarray:
    c = np.clip(np.asarray(c, float), 0.0, 1.0)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def load(folder: str | Path) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    folder = Path(folder)
    doc = json.loads((folder / "scene.json").read_text())
    with np.load(folder / "meshes.npz") as z:
        arrays = {k: z[k] for k in z.files}
    return doc, arrays


def reset() -> None:
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)


def add_mesh(name: str, v: np.ndarray, f: np.ndarray, uv: np.ndarray | None, world: np.ndarray, pass_index: int, mat):
    """One object from arrays (foreach_set: no Python loop over vertices)."""
    import bpy
    from mathutils import Matrix

    me = bpy.data.meshes.new(name)
    f = np.ascontiguousarray(f, np.int32)
    me.vertices.add(len(v))
    me.vertices.foreach_set("co", np.ascontiguousarray(v, np.float32).ravel())
    me.loops.add(f.size)
    me.loops.foreach_set("vertex_index", f.ravel())
    me.polygons.add(len(f))
    me.polygons.foreach_set("loop_start", np.arange(0, f.size, 3, dtype=np.int32))
    if uv is not None:
        layer = me.uv_layers.new(name="UVMap")
        layer.data.foreach_set("uv", np.ascontiguousarray(uv[f.ravel()], np.float32).ravel())
    me.update()
    me.shade_smooth()
    me.set_sharp_from_angle(angle=math.radians(SMOOTH_ANGLE_DEG))
    me.materials.append(mat)
    ob = bpy.data.objects.new(name, me)
    ob.matrix_world = Matrix(np.asarray(world, float).tolist())
    ob.pass_index = int(pass_index)
    bpy.context.scene.collection.objects.link(ob)
    return ob


def _image(folder: Path, rel: str, cache: dict):
    import bpy

    if rel not in cache:
        img = bpy.data.images.load(str(folder / rel), check_existing=False)
        img.colorspace_settings.name = "sRGB"
        cache[rel] = img
    return cache[rel]


def bsdf_params(look: dict[str, Any]) -> dict[str, float]:
    """MuJoCo material parameters -> Principled BSDF inputs (see the module docstring)."""
    spec, shin, refl = (
        float(look.get("specular", 0.3)),
        float(look.get("shininess", 0.3)),
        float(look.get("reflectance", 0.0)),
    )
    return {
        "Roughness": float(np.clip(1.0 - 0.9 * shin, 0.08, 1.0)),
        "Specular IOR Level": float(np.clip(spec, 0.0, 1.0)),
        "Metallic": 1.0 if refl >= 0.15 else 0.0,
        "Coat Weight": float(np.clip(refl * 4.0, 0.0, 0.5)) if refl < 0.15 else 0.0,
    }


def make_material(name: str, look: dict[str, Any], folder: Path, images: dict):
    import bpy

    m = bpy.data.materials.new(name)
    nt = m.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    for k, val in bsdf_params(look).items():
        bsdf.inputs[k].default_value = val
    base = (*srgb_to_linear(look["rgba"][:3]), 1.0)
    tex_file = look.get("texture_file")
    if not tex_file:
        bsdf.inputs["Base Color"].default_value = base
        return m
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = _image(folder, tex_file, images)
    tex.interpolation, tex.extension = "Linear", "REPEAT"
    if look.get("repeat"):  # tiled procedural texture: UVs are metres, `repeat` tiles per metre
        coord, mapping = nt.nodes.new("ShaderNodeTexCoord"), nt.nodes.new("ShaderNodeMapping")
        mapping.inputs["Scale"].default_value = (float(look["repeat"][0]), float(look["repeat"][1]), 1.0)
        nt.links.new(coord.outputs["UV"], mapping.inputs["Vector"])
        nt.links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
    if max(abs(x - 1.0) for x in base[:3]) < 1e-6:
        nt.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
        return m
    mix = nt.nodes.new("ShaderNodeMix")
    mix.data_type, mix.blend_type = "RGBA", "MULTIPLY"
    mix.inputs["Factor"].default_value = 1.0
    nt.links.new(tex.outputs["Color"], mix.inputs[6])  # A
    mix.inputs[7].default_value = base  # B
    nt.links.new(mix.outputs[2], bsdf.inputs["Base Color"])
    return m


def _aim(direction: np.ndarray) -> np.ndarray:
    """A rotation whose -z axis points along `direction` (Blender lights shine down their -z)."""
    z = -np.asarray(direction, float) / np.linalg.norm(direction)
    x = np.cross([0.0, 0.0, 1.0], z) if abs(z[2]) < 0.999 else np.array([1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z], axis=1)


def spot_distance(pos, direction, target_z: float) -> float:
    """How far the spot's axis travels before it reaches the objects' height (clipped to 0.3-20 m)."""
    dz = float(direction[2])
    d = (target_z - float(pos[2])) / dz if dz < -1e-3 else 2.5
    return float(np.clip(d, 0.3, 20.0))


def add_lights(lights: list[dict[str, Any]], ambient: float, target_z: float, gain: float, ambient_gain: float) -> None:
    import bpy
    from mathutils import Matrix

    for i, L in enumerate(lights):
        level = gain * float(L["base"]) * float(L["intensity"])
        if L["kind"] == "directional":
            li = bpy.data.lights.new(f"light{i}", "SUN")
            li.energy, li.angle = math.pi * level, math.radians(SUN_ANGLE_DEG)
        else:
            li = bpy.data.lights.new(f"light{i}", "SPOT")
            d = spot_distance(L["pos"], L["direction"], target_z)
            li.energy = 4.0 * math.pi**2 * d * d * level
            li.spot_size, li.spot_blend = 2.0 * math.radians(float(L["cutoff_deg"])), SPOT_BLEND
            li.shadow_soft_size = SPOT_RADIUS
        li.color = tuple(float(x) for x in L["color"])
        li.use_shadow = True  # MuJoCo shadows only the key light to save time; a path tracer shadows every light
        ob = bpy.data.objects.new(f"light{i}", li)
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = _aim(L["direction"]), L["pos"]
        ob.matrix_world = Matrix(T.tolist())
        bpy.context.scene.collection.objects.link(ob)
    world = bpy.data.worlds.new("world")
    bpy.context.scene.world = world
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    bg.inputs["Strength"].default_value = float(ambient) * ambient_gain


def set_camera(cam_obj, cam: dict[str, Any]) -> None:
    """OpenCV intrinsics and pose -> Blender camera, exactly. Measured on Blender 5.0 (a test ray-casts two
    planes): with a horizontal sensor fit fx = lens W / sensor, fy = fx * pixel_aspect_x / pixel_aspect_y,
    cx = W/2 - shift_x W and cy = H/2 + shift_y W fy / fx (shifts are in units of the fitted width)."""
    import bpy
    from mathutils import Matrix

    sc = bpy.context.scene
    W, H = int(cam["width"]), int(cam["height"])
    fx, fy, cx, cy = (float(cam[k]) for k in ("fx", "fy", "cx", "cy"))
    r = fy / fx
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = W, H, 100
    sc.render.pixel_aspect_x, sc.render.pixel_aspect_y = (r, 1.0) if r >= 1.0 else (1.0, 1.0 / r)
    cd = cam_obj.data
    cd.sensor_fit, cd.sensor_width = "HORIZONTAL", 36.0
    cd.lens = fx * 36.0 / W
    cd.shift_x, cd.shift_y = (W / 2.0 - cx) / W, (cy - H / 2.0) / (W * r)
    cd.clip_start, cd.clip_end = 0.01, 100.0
    T = np.asarray(cam["world_from_cam"], float) @ np.diag([1.0, -1.0, -1.0, 1.0])  # OpenCV -> Blender camera axes
    cam_obj.matrix_world = Matrix(T.tolist())


def build(folder: str | Path, light_gain: float = 1.0, ambient_gain: float = 1.0) -> dict[str, Any]:
    """Reset Blender and build the described scene (meshes, materials, lights, a camera). Returns scene.json."""
    import bpy

    folder = Path(folder)
    doc, arrays = load(folder)
    reset()
    mats: dict[str, Any] = {}
    images: dict[str, Any] = {}
    obj_z = []
    for m in doc["meshes"]:
        key = json.dumps(m["look"], sort_keys=True)
        if key not in mats:
            mats[key] = make_material(f"mat{len(mats)}", m["look"], folder, images)
        i = m["arrays"]
        add_mesh(
            m["name"],
            arrays[f"v{i}"],
            arrays[f"f{i}"],
            arrays.get(f"uv{i}") if m["has_uv"] else None,
            np.asarray(m["world_from_local"]),
            m["instance_id"],
            mats[key],
        )
        if m["instance_id"] > 0:
            obj_z.append(float(m["world_from_local"][2][3]))
    target_z = float(np.median(obj_z)) if obj_z else 0.8
    add_lights(doc["lights"], float(doc.get("ambient", 0.3)), target_z, light_gain, ambient_gain)
    cd = bpy.data.cameras.new("camera")
    co = bpy.data.objects.new("camera", cd)
    bpy.context.scene.collection.objects.link(co)
    bpy.context.scene.camera = co
    return doc
