"""The MuJoCo model of a SceneDesc (MjSpec): room, furniture, lights, and one free body per object.

Visual meshes are drawn only; collision uses convex pieces (boxes, cylinders, convex meshes) in a hidden
group. Every surface's look comes from looks.py and every light from desc.lights, so a second renderer
given the same SceneDesc draws the same scene.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from refspatial_gen.assets.shapes import AssetGeometry, Part, quat_from_matrix, rot_axis
from refspatial_gen.core.errors import DropUnit
from refspatial_gen.sources.sim.layout import SceneDesc, StaticBox
from refspatial_gen.sources.sim.looks import Look, floor_look, furniture_look, part_look

GEOM_TYPES = {
    "box": mujoco.mjtGeom.mjGEOM_BOX,
    "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
    "sphere": mujoco.mjtGeom.mjGEOM_SPHERE,
    "capsule": mujoco.mjtGeom.mjGEOM_CAPSULE,
    "ellipsoid": mujoco.mjtGeom.mjGEOM_ELLIPSOID,
    "mesh": mujoco.mjtGeom.mjGEOM_MESH,
}
HIDDEN_GROUP = 3  # collision-only geoms live in this group; renders switch it off
WALL_HEIGHT = 2.6


@dataclass
class SimModel:
    model: mujoco.MjModel
    data: mujoco.MjData
    body_ids: list[int]  # per desc.objects
    geom_object: np.ndarray  # geom id -> object index + 1 (0 = furniture/room)
    n_views: int


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
    inertia = second - mass * (np.dot(com, com) * np.eye(3) - np.outer(com, com))
    scale = max(0.02, mass) / mass
    mass, inertia = mass * scale, inertia * scale
    inertia = (inertia + inertia.T) / 2
    w, V = np.linalg.eigh(inertia)
    if np.linalg.det(V) < 0:
        V[:, 0] *= -1
    return mass, com, np.maximum(w, 1e-8), quat_from_matrix(V)


class _Materials:
    """MuJoCo materials and textures of one spec, made once per distinct Look."""

    def __init__(self, spec: mujoco.MjSpec):
        self.spec, self.mats, self.texs = spec, {}, {}

    def texture(self, look: Look) -> str:
        key = look.texture_key or f"img{id(look.texture)}"
        if key not in self.texs:
            t = self.spec.add_texture()
            t.name = f"tex{len(self.texs)}"
            t.type = mujoco.mjtTexture.mjTEXTURE_2D
            img = np.ascontiguousarray(look.texture[::-1])  # MuJoCo's first row is v = 0 (bottom)
            t.height, t.width, t.nchannel = img.shape[0], img.shape[1], 3
            t.data = img.tobytes()
            self.texs[key] = t.name
        return self.texs[key]

    def get(self, look: Look) -> str:
        """A material for `look`. Tiled textures use texuniform (size by world extent); UV-mapped ones must
        not: MuJoCo's texuniform ignores a mesh's texcoords, so a UV atlas would be sampled at one texel."""
        key = (
            tuple(round(x, 5) for x in look.rgba),
            look.specular,
            look.shininess,
            look.reflectance,
            look.texture_key,
            None if look.texture is None else id(look.texture),
            look.repeat,
        )
        if key in self.mats:
            return self.mats[key]
        m = self.spec.add_material()
        m.name = f"mat{len(self.mats)}"
        m.rgba = list(look.rgba)
        m.specular, m.shininess, m.reflectance = look.specular, look.shininess, look.reflectance
        if look.texture is not None:
            m.textures[int(mujoco.mjtTextureRole.mjTEXROLE_RGB)] = self.texture(look)
            m.texrepeat = list(look.repeat) if look.repeat is not None else [1.0, 1.0]
            m.texuniform = look.repeat is not None
        self.mats[key] = m.name
        return m.name


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
        if part.uv is not None and part.visual:
            m.usertexcoord = np.asarray(part.uv, np.float32).ravel().tolist()
        g.meshname = m.name
    else:
        g.size = list(part.size) + [0.0] * (3 - len(part.size))
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


def room_statics(desc: SceneDesc) -> list[StaticBox]:
    """Furniture plus the four walls (when the scene has walls)."""
    statics = list(desc.statics)
    if desc.walls:
        rx, ry = desc.room_half
        h = WALL_HEIGHT / 2
        statics += [
            StaticBox("wall_back", np.array([0, ry + 0.05, h]), np.array([rx + 0.1, 0.05, h]), "wall"),
            StaticBox("wall_left", np.array([-rx - 0.05, 0, h]), np.array([0.05, ry + 0.1, h]), "wall"),
            StaticBox("wall_front", np.array([0, -ry - 0.05, h]), np.array([rx + 0.1, 0.05, h]), "wall"),
            StaticBox("wall_right", np.array([rx + 0.05, 0, h]), np.array([0.05, ry + 0.1, h]), "wall"),
        ]
    return statics


def _lights(spec: mujoco.MjSpec, desc: SceneDesc) -> None:
    for L in desc.lights:
        li = spec.worldbody.add_light()
        li.type = (
            mujoco.mjtLightType.mjLIGHT_DIRECTIONAL if L.kind == "directional" else mujoco.mjtLightType.mjLIGHT_SPOT
        )
        li.pos, li.dir = [float(x) for x in L.pos], [float(x) for x in L.direction]
        li.diffuse = [float(x) for x in L.diffuse()]
        li.specular = [0.15 * L.intensity] * 3
        li.castshadow = bool(L.shadow)
        if L.kind == "spot":
            li.cutoff, li.exponent = float(L.cutoff_deg), 2.0
            li.attenuation = [1.0, 0.0, 0.0]


def build_model(
    desc: SceneDesc, catalog_materials: dict[str, dict[str, float]], cfg: dict[str, Any], n_views: int
) -> SimModel:
    spec = mujoco.MjSpec()
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    spec.option.timestep = float(cfg.get("timestep", 0.002))
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.visual.global_.offwidth = int(cfg.get("width", 640))
    spec.visual.global_.offheight = int(cfg.get("height", 480))
    spec.visual.quality.offsamples = 0  # no MSAA: blended edge pixels would corrupt segmentation ids and depth
    spec.visual.quality.shadowsize = int(cfg.get("shadow_size", 2048)) or 2048
    spec.visual.map.shadowclip = 0.45  # a tighter directional-light shadow frustum: sharper shadows, same cost
    ap = desc.appearance
    spec.visual.headlight.ambient = [ap["ambient"]] * 3
    spec.visual.headlight.diffuse = [ap.get("headlight", 0.15)] * 3
    spec.visual.headlight.specular = [0.03] * 3
    wb = spec.worldbody
    _lights(spec, desc)
    mats = _Materials(spec)
    fl = wb.add_geom()
    fl.name = "floor"
    fl.type = mujoco.mjtGeom.mjGEOM_PLANE
    fl.size = [float(desc.room_half[0]) + 2, float(desc.room_half[1]) + 2, 0.1]
    if not desc.floor:  # single-object renders: keep the geom (names stay stable) but never draw or collide it
        fl.group, fl.contype, fl.conaffinity, fl.rgba = HIDDEN_GROUP, 0, 0, [0, 0, 0, 0]
    else:
        fl.material = mats.get(floor_look(ap))
    for sb in room_statics(desc):
        g = wb.add_geom()
        g.name = sb.name
        g.type = mujoco.mjtGeom.mjGEOM_BOX
        g.size = list(map(float, sb.half))
        g.pos = list(map(float, sb.center))
        g.material = mats.get(furniture_look(sb.look, ap))
        g.friction = [0.8, 0.02, 0.001]
    colors = cfg.get("_colors", {})
    body_names = []
    for o in desc.objects:
        b = wb.add_body()
        b.name = o.key
        b.pos = list(map(float, o.pos))
        b.quat = quat_from_matrix(rot_axis("z", o.yaw))
        b.add_freejoint()
        mass, com, inertia, iquat = _inertial(o.geometry)
        b.explicitinertial = True
        b.mass, b.ipos, b.inertia, b.iquat = mass, com, inertia, iquat
        condim = 6 if o.geometry.rolls else 4
        fric = (0.9, 0.02, 0.002 if o.geometry.rolls else 0.0001)
        for j, p in enumerate(o.geometry.parts):
            mat = mats.get(part_look(o, p, colors, catalog_materials)) if p.visual else ""
            _add_part(spec, b, p, f"{o.key}_g{j}", mat, fric, condim)
        body_names.append(o.key)
    for v in range(n_views):
        wb.add_camera().name = f"view{v}"
    try:
        model = spec.compile()
    except ValueError as e:
        raise DropUnit("model_compile_failed", str(e)[:300]) from e
    data = mujoco.MjData(model)
    body_ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, n) for n in body_names]
    body_obj = np.zeros(model.nbody, int)
    for k, bid in enumerate(body_ids):
        body_obj[bid] = k + 1
    return SimModel(model, data, body_ids, body_obj[model.geom_bodyid], n_views)
