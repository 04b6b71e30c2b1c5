"""MuJoCo model from a SceneDesc (MjSpec), and physics until everything is at rest.

Why a velocity criterion: a fixed step count either wastes time on quiet scenes or stops a rolling
object mid-motion; we step in chunks until every free body is slower than a threshold for several
consecutive checks, and drop the scene (`physics_not_settled`) when the step cap is reached.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import mujoco
import numpy as np

from refspatial_gen.assets.shapes import AssetGeometry, Part, quat_from_matrix, rot_axis
from refspatial_gen.core.errors import DropUnit
from refspatial_gen.sources.sim.layout import SceneDesc

GEOM_TYPES = {"box": mujoco.mjtGeom.mjGEOM_BOX, "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER, "sphere": mujoco.mjtGeom.mjGEOM_SPHERE,
              "capsule": mujoco.mjtGeom.mjGEOM_CAPSULE, "ellipsoid": mujoco.mjtGeom.mjGEOM_ELLIPSOID, "mesh": mujoco.mjtGeom.mjGEOM_MESH}
HIDDEN_GROUP = 3  # collision-only geoms live in this group; renders switch it off


@dataclass
class SimModel:
    model: mujoco.MjModel
    data: mujoco.MjData
    body_ids: list[int]  # per desc.objects
    geom_object: np.ndarray  # geom id -> object index + 1 (0 = furniture/room)
    n_views: int


# ----------------------------------------------------------------------------------- textures

@lru_cache(maxsize=8)
def _wood_texture(variant: int, size: int = 256) -> bytes:
    """A deterministic procedural texture (RGB bytes): wood grain (variants 0-2) or speckled laminate (3)."""
    r = np.random.default_rng(1000 + variant)
    y, x = np.mgrid[0:size, 0:size] / size
    if variant % 4 == 3:
        base = 0.8 + 0.12 * r.random((size, size))
        img = np.stack([base, base * 0.98, base * 0.95], -1)
    else:
        # grain along x: fine lines whose phase drifts slowly, plus plank seams
        drift = np.cumsum(r.normal(0, 1, size)) / size * 0.6
        lines = np.sin(2 * np.pi * (y * [60, 90, 45][variant] + drift[None, :] * 4 + 0.3 * np.sin(2 * np.pi * x * 2)))
        fine = r.random((size, 1)) * 0.15 + r.random((size, size)) * 0.04
        planks = ((y * 4) % 1.0 < 0.012).astype(float) * 0.25
        v = 0.78 + 0.07 * lines + fine - planks
        img = np.stack([v, v * 0.8, v * 0.6], -1)
    return (np.clip(img, 0, 1) * 255).astype(np.uint8).tobytes()


@lru_cache(maxsize=32)
def _image_texture(path: str, size: int = 512) -> tuple[bytes, int, int]:
    """An image file downsampled for MuJoCo (textures are re-uploaded for every scene: keep them small)."""
    from PIL import Image

    im = Image.open(path).convert("RGB")
    im = im.resize((min(size, im.width), min(size, im.height)), Image.BILINEAR)
    return np.asarray(im, np.uint8)[::-1].tobytes(), im.width, im.height


# ----------------------------------------------------------------------------------- model

def _inertial(geo: AssetGeometry) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    """Mass, centre of mass, principal inertia and its frame from the solid (colliding) parts.

    Summing the parts (not the overall hull) puts the centre of mass where the material is: a floor
    lamp's heavy base, a mug's walls, not the middle of their bounding volume.
    """
    mass, first, second = 0.0, np.zeros(3), np.zeros((3, 3))
    for p in geo.parts:
        if not p.collide:
            continue
        m = p.trimesh()
        if p.kind == "mesh" and not m.is_watertight:
            m = m.convex_hull
        vol = abs(float(m.volume))
        if vol <= 0:
            continue
        mk = geo.density * vol
        c = np.asarray(m.center_mass)
        Ik = np.asarray(m.moment_inertia) * (mk / m.volume)  # about its own centre of mass
        mass += mk
        first += mk * c
        second += Ik + mk * (np.dot(c, c) * np.eye(3) - np.outer(c, c))
    if mass <= 0:
        raise DropUnit("asset_degenerate", "object has no solid part")
    com = first / mass
    I = second - mass * (np.dot(com, com) * np.eye(3) - np.outer(com, com))
    scale = max(0.02, mass) / mass
    mass, I = mass * scale, I * scale
    I = (I + I.T) / 2
    w, V = np.linalg.eigh(I)
    if np.linalg.det(V) < 0:
        V[:, 0] *= -1
    return mass, com, np.maximum(w, 1e-8), quat_from_matrix(V)


def _add_part(spec: mujoco.MjSpec, body, part: Part, name: str, mat: str, friction: tuple, condim: int) -> None:
    g = body.add_geom()
    g.name = name
    g.type = GEOM_TYPES[part.kind]
    if part.kind == "mesh":
        m = spec.add_mesh()
        m.name = name + "_mesh"
        m.uservert = np.asarray(part.mesh.vertices, np.float32).ravel().tolist()
        m.userface = np.asarray(part.mesh.faces, np.int32).ravel().tolist()
        m.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
        if part.uv is not None:
            m.usertexcoord = np.asarray(part.uv, np.float32).ravel().tolist()
        g.meshname = m.name
    else:
        size = list(part.size) + [0.0] * (3 - len(part.size))
        g.size = size
    g.pos = np.asarray(part.pos, float)
    g.quat = quat_from_matrix(part.rot)
    g.material = mat
    g.friction = friction
    g.condim = condim
    if not part.collide:
        g.contype, g.conaffinity = 0, 0
    if not part.visual:
        g.group = HIDDEN_GROUP
        g.rgba = [0.5, 0.5, 0.5, 0.0]


def _material(spec, name: str, rgb, params: dict[str, float], texture: str | None = None,
              repeat: tuple[float, float] | None = None) -> str:
    """A material; `texture` with `repeat` is tiled by world size (procedural wood, checker), without
    `repeat` it is mapped by the mesh's own texture coordinates (authored UVs of scanned/imported meshes).

    Why the distinction: MuJoCo's `texuniform` ignores a mesh's texcoords, so a UV atlas (YCB) rendered
    with it samples one texel of the atlas everywhere and the object comes out a flat (often black) colour.
    """
    m = spec.add_material()
    m.name = name
    m.rgba = [float(rgb[0]), float(rgb[1]), float(rgb[2]), float(params.get("alpha", 1.0))]
    m.specular = params.get("specular", 0.3)
    m.shininess = params.get("shininess", 0.3)
    m.reflectance = params.get("reflectance", 0.0)
    if texture:
        m.textures[int(mujoco.mjtTextureRole.mjTEXROLE_RGB)] = texture
        m.texrepeat = list(repeat) if repeat is not None else [1.0, 1.0]
        m.texuniform = repeat is not None
    return name


def _add_texture(spec, name: str, data: bytes, w: int, h: int) -> str:
    t = spec.add_texture()
    t.name = name
    t.type = mujoco.mjtTexture.mjTEXTURE_2D
    t.width, t.height, t.nchannel = w, h, 3
    t.data = data
    return name


def build_model(desc: SceneDesc, catalog_materials: dict[str, dict[str, float]], cfg: dict[str, Any], n_views: int) -> SimModel:
    spec = mujoco.MjSpec()
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    spec.option.timestep = float(cfg.get("timestep", 0.002))
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.visual.global_.offwidth = int(cfg.get("width", 640))
    spec.visual.global_.offheight = int(cfg.get("height", 480))
    spec.visual.quality.offsamples = 0  # no MSAA: blended edge pixels would corrupt segmentation ids and depth
    spec.visual.quality.shadowsize = int(cfg.get("shadow_size", 0)) or 1024
    ap = desc.appearance
    spec.visual.headlight.ambient = [ap["ambient"]] * 3
    spec.visual.headlight.diffuse = [0.25] * 3
    spec.visual.headlight.specular = [0.05] * 3
    wb = spec.worldbody

    # lights: one main directional light (optionally casting shadows) and a fill light
    L = wb.add_light()
    L.type = mujoco.mjtLightType.mjLIGHT_DIRECTIONAL
    L.dir = ap["light_dir"]
    L.pos = [0, 0, 3]
    L.diffuse = list(ap["light_diffuse"] * np.asarray(ap["light_warm"]))
    L.specular = [0.2] * 3
    L.castshadow = bool(cfg.get("shadow_size", 0))
    L2 = wb.add_light()
    L2.type = mujoco.mjtLightType.mjLIGHT_DIRECTIONAL
    L2.dir = [-ap["light_dir"][0], -ap["light_dir"][1], -1.0]
    L2.diffuse = [0.2] * 3
    L2.castshadow = False

    # room: floor plane, walls, furniture
    _add_texture(spec, "tex_table", _wood_texture(ap["table_tex"]), 256, 256)
    _add_texture(spec, "tex_floor", _wood_texture((ap["floor_tex"] + 1) % 3), 256, 256)
    fl = wb.add_geom()
    fl.name = "floor"
    fl.type = mujoco.mjtGeom.mjGEOM_PLANE
    fl.size = [float(desc.room_half[0]) + 2, float(desc.room_half[1]) + 2, 0.1]
    if not desc.floor:  # single-object renders: keep the geom (names stay stable) but never draw or collide it
        fl.group, fl.contype, fl.conaffinity, fl.rgba = HIDDEN_GROUP, 0, 0, [0, 0, 0, 0]
    elif ap["floor_tex"] == 0:
        t = spec.add_texture()
        t.name, t.type, t.builtin = "tex_checker", mujoco.mjtTexture.mjTEXTURE_2D, mujoco.mjtBuiltin.mjBUILTIN_CHECKER
        t.width, t.height = 256, 256
        t.rgb1, t.rgb2 = list(ap["floor_rgb1"]), list(ap["floor_rgb1"] * 0.82)
        fl.material = _material(spec, "mat_floor", [1, 1, 1], {"specular": 0.1}, "tex_checker", (3, 3))
    else:
        fl.material = _material(spec, "mat_floor", ap["floor_rgb1"] * 0.6 + 0.3, {"specular": 0.2}, "tex_floor", (0.7, 0.7))
    looks = {"table": _material(spec, "mat_table", ap["table_tint"], {"specular": 0.3, "shininess": 0.4}, "tex_table", (1.2, 1.2)),
             "counter": _material(spec, "mat_counter", ap["counter_rgb"], {"specular": 0.4}),
             "shelf": _material(spec, "mat_shelf", ap["table_tint"] * 0.8, {"specular": 0.2}, "tex_table", (1, 1)),
             "leg": _material(spec, "mat_leg", [0.25, 0.22, 0.2], {"specular": 0.3}),
             "wall": _material(spec, "mat_wall", ap["wall_rgb"], {"specular": 0.05})}
    statics = list(desc.statics)
    if desc.walls:
        rx, ry = desc.room_half
        from refspatial_gen.sources.sim.layout import StaticBox

        statics.append(StaticBox("wall_back", np.array([0, ry + 0.05, 1.3]), np.array([rx + 0.1, 0.05, 1.3]), "wall"))
        statics.append(StaticBox("wall_left", np.array([-rx - 0.05, 0, 1.3]), np.array([0.05, ry + 0.1, 1.3]), "wall"))
        statics.append(StaticBox("wall_front", np.array([0, -ry - 0.05, 1.3]), np.array([rx + 0.1, 0.05, 1.3]), "wall"))
        statics.append(StaticBox("wall_right", np.array([rx + 0.05, 0, 1.3]), np.array([0.05, ry + 0.1, 1.3]), "wall"))
    for sb in statics:
        g = wb.add_geom()
        g.name = sb.name
        g.type = mujoco.mjtGeom.mjGEOM_BOX
        g.size = list(map(float, sb.half))
        g.pos = list(map(float, sb.center))
        g.material = looks[sb.look]
        g.friction = [0.8, 0.02, 0.001]

    # objects: one free body each
    body_names = []
    tex_done: dict[str, str] = {}
    for i, o in enumerate(desc.objects):
        b = wb.add_body()
        b.name = o.key
        b.pos = list(map(float, o.pos))
        b.quat = quat_from_matrix(rot_axis("z", o.yaw))
        b.add_freejoint()
        mass, com, inertia, iquat = _inertial(o.geometry)
        b.explicitinertial = True
        b.mass, b.ipos, b.inertia, b.iquat = mass, com, inertia, iquat
        mp = catalog_materials[o.material]
        mats = {"body": _material(spec, f"{o.key}_body", o.rgb, mp), "accent": _material(spec, f"{o.key}_acc", o.accent_rgb, mp)}
        condim = 6 if o.geometry.rolls else 4
        fric = (0.9, 0.02, 0.002 if o.geometry.rolls else 0.0001)
        for j, p in enumerate(o.geometry.parts):
            if p.texture:
                if p.texture not in tex_done:
                    data, w, h = _image_texture(p.texture)
                    tex_done[p.texture] = _add_texture(spec, f"tex_ext{len(tex_done)}", data, w, h)
                key = f"{o.key}_tex"
                if key not in mats:
                    mats[key] = _material(spec, key, [1, 1, 1], mp, tex_done[p.texture])
                mat = mats[key]
            elif p.role in mats:
                mat = mats[p.role]
            else:
                key = f"{o.key}_{p.role}"
                if key not in mats:
                    mats[key] = _material(spec, key, cfg["_colors"].get(p.role, (0.5, 0.5, 0.5)), mp)
                mat = mats[key]
            _add_part(spec, b, p, f"{o.key}_g{j}", mat, fric, condim)
        body_names.append(o.key)
    for v in range(n_views):
        c = wb.add_camera()
        c.name = f"view{v}"
    try:
        model = spec.compile()
    except ValueError as e:
        raise DropUnit("model_compile_failed", str(e)[:300]) from e
    data = mujoco.MjData(model)
    body_ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, n) for n in body_names]
    body_obj = np.zeros(model.nbody, int)
    for k, bid in enumerate(body_ids):
        body_obj[bid] = k + 1
    geom_object = body_obj[model.geom_bodyid]
    return SimModel(model, data, body_ids, geom_object, n_views)


def settle(sim: SimModel, cfg: dict[str, Any]) -> dict[str, float]:
    """Step until all free bodies are at rest; raise DropUnit when they are not after the step cap."""
    m, d = sim.model, sim.data
    mujoco.mj_forward(m, d)
    lin_tol, ang_tol = float(cfg.get("settle_lin_vel", 0.005)), float(cfg.get("settle_ang_vel", 0.05))
    cap, chunk, need = int(cfg.get("settle_max_steps", 3000)), 25, 3
    steps, quiet = 0, 0
    lin = ang = 0.0
    while steps < cap:
        for _ in range(chunk):
            mujoco.mj_step(m, d)
        steps += chunk
        if m.nv == 0:
            break
        v = d.qvel.reshape(-1, 6)
        lin, ang = float(np.abs(v[:, :3]).max()), float(np.abs(v[:, 3:]).max())
        if not np.all(np.isfinite(d.qvel)):
            raise DropUnit("physics_unstable", "non-finite velocities")
        quiet = quiet + 1 if (lin < lin_tol and ang < ang_tol) else 0
        if quiet >= need and steps >= 100:
            break
    else:
        raise DropUnit("physics_not_settled", f"max speed {lin:.3f} m/s, {ang:.3f} rad/s after {steps} steps")
    if d.ncon:
        pen = -float(d.contact.dist[: d.ncon].min())
        if pen > float(cfg.get("max_penetration", 0.006)):
            raise DropUnit("interpenetration", f"contact penetration {pen * 1000:.1f} mm after settling")
    return {"steps": steps, "sim_time": steps * m.opt.timestep, "max_lin_vel": lin, "max_ang_vel": ang}


def body_pose(sim: SimModel, k: int) -> tuple[np.ndarray, np.ndarray]:
    """World position and rotation matrix of object k's body frame (origin = bottom centre at placement)."""
    bid = sim.body_ids[k]
    return sim.data.xpos[bid].copy(), sim.data.xmat[bid].reshape(3, 3).copy()
