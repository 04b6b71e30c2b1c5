"""Textured real-object libraries that ship inside package-registry wheels, unpacked at set-up time.

`make assets-textured` downloads the wheel once (`pip download --no-deps`, never at run time), and
`python -m refspatial_gen.assets.library robosuite WHEEL_DIR DEST` unpacks only the object meshes, their
MTL files and textures into DEST (a cache folder outside git) with an `annotations.json` giving each
object its category words and materials; `refspatial-gen assets import DEST/objects/robosuite` then makes
the catalog like for any folder.

Why robosuite: MIT licence, six textured household objects (OBJ + MTL + PNG) and material textures in
one wheel. pybullet_data (zlib) holds mostly untextured procedural shapes; LIBERO-PRO's asset packages
mix sources whose licences must be checked one by one (see docs/sim.md).
"""

from __future__ import annotations

import json
import shutil
import sys
import zipfile
from pathlib import Path

LIBRARIES = {
    "robosuite": {
        "requirement": "robosuite==1.5.2",
        "licence": "MIT (Copyright (c) 2022 Stanford Vision and Learning Lab and UT Robot Perception and Learning Lab)",
        "prefix": "robosuite/models/assets/",
        "objects": {  # mesh stem -> annotation (category words, materials)
            "bottle": {"category": "bottle", "materials": ["glass"]},
            "bread": {"category": "bread", "materials": ["organic"]},
            "can": {"category": "soda can", "materials": ["metal"]},
            "cereal": {
                "category": "cereal box",
                "materials": ["cardboard"],
                "front": "-y",
                "front_phrase": "the front panel",
            },
            "lemon": {"category": "lemon", "materials": ["organic"]},
            "milk": {"category": "milk carton", "materials": ["cardboard"]},
        },
    },
}


def unpack(name: str, wheel_dir: Path, dest: Path) -> Path:
    """Unpack library `name` from its wheel in `wheel_dir` into `dest`; returns the folder to import."""
    lib = LIBRARIES[name]
    dist = lib["requirement"].split("==")[0].replace("-", "_")
    wheels = sorted(Path(wheel_dir).glob(f"{dist}-{lib['requirement'].split('==')[1]}-*.whl"))
    if not wheels:
        raise FileNotFoundError(
            f"no {lib['requirement']} wheel in {wheel_dir}: run `pip download --no-deps {lib['requirement']}`"
        )
    tmp = dest.with_name(dest.name + ".tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    prefix = lib["prefix"]
    wanted = {f"{prefix}objects/meshes/{stem}.{ext}" for stem in lib["objects"] for ext in ("obj", "mtl")}
    folder = f"objects/{name}"  # named after the library: catalog entries become "robosuite cereal" ...
    with zipfile.ZipFile(wheels[0]) as z:
        for info in z.infolist():
            n = info.filename
            if n in wanted or (n.startswith(prefix + "textures/") and n.endswith(".png")) or n.endswith("LICENSE"):
                rel = n[len(prefix) :] if n.startswith(prefix) else "LICENSE"
                rel = rel.replace(
                    "objects/meshes/", folder + "/"
                )  # same depth: the MTLs' ../../textures/ still resolve
                (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
                (tmp / rel).write_bytes(z.read(n))
    (tmp / folder / "annotations.json").write_text(json.dumps(lib["objects"], indent=1))
    (tmp / "SOURCE.txt").write_text(f"{lib['requirement']} (wheel {wheels[0].name}); licence: {lib['licence']}\n")
    shutil.rmtree(dest, ignore_errors=True)
    tmp.rename(dest)
    return dest / folder


if __name__ == "__main__":
    if len(sys.argv) != 4 or sys.argv[1] not in LIBRARIES:
        sys.exit(f"usage: python -m refspatial_gen.assets.library {{{','.join(LIBRARIES)}}} WHEEL_DIR DEST")
    print(unpack(sys.argv[1], Path(sys.argv[2]), Path(sys.argv[3])))
