"""CLI: `refspatial-gen assets list|import|sheet|set-front` (the simulated source's asset catalogs)."""

from __future__ import annotations

import argparse
import json


def cmd_list(args) -> int:
    from refspatial_gen.assets import load_catalog
    from refspatial_gen.assets.external import external_available

    cat = load_catalog(args.catalog or None)
    rows = []
    for n, c in cat.categories.items():
        rows.append(
            {
                "name": n,
                "label": c.label,
                "builder": c.builder,
                "scale": c.scale,
                "dims": {k: list(v) for k, v in c.dims.items()},
                "colors": list(c.colors),
                "materials": list(c.materials),
                "front": None if c.front is None else list(c.front),
                "front_phrase": c.front_phrase,
                "fits_inside": c.fits_inside,
                "available": c.builder != "external" or external_available(c),
                "defined_in": f"{c.origin[0]}:{c.origin[1]}",
            }
        )
    if args.json:
        print(json.dumps({"catalog": cat.path, "files": list(cat.files), "categories": rows}, indent=1, sort_keys=True))
        return 0
    print(
        f"{len(rows)} categories in {cat.path}" + (f" (with {', '.join(cat.files[:-1])})" if len(cat.files) > 1 else "")
    )
    for r in rows:
        front = f"front: {r['front_phrase']}" if r["front_phrase"] else ""
        print(f"  {r['name']:28s} {r['scale']:8s} {r['builder']:9s} {','.join(r['colors'][:4]):28s} {front}")
    return 0


def cmd_import(args) -> int:
    from refspatial_gen.assets.importer import import_assets

    def show(r):
        print(
            f"  {r['name']:34s} {r['label']:18s} {'x'.join(f'{x:.3f}' for x in r['size_m'])} m  "
            f"{'textured' if r['textured'] else 'untextured':10s} collision: {r['collision']}",
            flush=True,
        )

    try:
        rows = import_assets(args.dirs, args.out, args.cache or None, args.collision, args.include, progress=show)
    except (FileNotFoundError, ValueError) as e:
        print(f"error: {e}")
        return 2
    from refspatial_gen.assets import load_catalog

    cat = load_catalog(args.out)  # proves the written file loads: every path resolves
    print(f"wrote {args.out}: {len(rows)} assets (catalog now {len(cat.categories)} categories with the built-in ones)")
    return 0


def cmd_sheet(args) -> int:
    from refspatial_gen.sources.sim.sheet import asset_sheet

    print(json.dumps(asset_sheet(args.out, args.catalog or None, args.names or None, args.px)))
    return 0


def cmd_set_front(args) -> int:
    from refspatial_gen.assets import load_catalog
    from refspatial_gen.assets.edit import set_front

    try:
        file, front = set_front(load_catalog(args.catalog or None), args.name, args.direction, args.phrase)
    except (KeyError, ValueError) as e:
        print(f"error: {e.args[0]}")
        return 2
    print(f'{file}: {args.name}: front {front} "{args.phrase}"')
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    a = sub.add_parser("assets", help="asset catalogs of the simulated source: list, import, sheet, set-front")
    asub = a.add_subparsers(dest="assets_command", required=True)
    ls = asub.add_parser("list", help="list catalog categories")
    ls.add_argument("--json", action="store_true")
    ls.add_argument("--catalog", default="", help="catalog YAML (default: the built-in assets/catalog.yaml)")
    ls.set_defaults(func=cmd_list)
    im = asub.add_parser("import", help="write a catalog (extending the built-in one) for the meshes in folders")
    im.add_argument(
        "dirs",
        nargs="+",
        help="folders of GLB/glTF, OBJ(+MTL), STL, PLY, USD(z) files (objects.json / annotations read)",
    )
    im.add_argument("--out", required=True, help="catalog YAML to write")
    im.add_argument(
        "--cache",
        default="",
        help="asset cache for convex decompositions (default $REFSPATIAL_CACHE or ~/.cache/refspatial-gen)",
    )
    im.add_argument(
        "--collision",
        choices=["auto", "coacd", "hull"],
        default="auto",
        help="auto: shipped convex parts, else CoACD (hull for nearly convex meshes)",
    )
    im.add_argument("--include", default="builtin", help="catalog the new one extends (default: builtin)")
    im.set_defaults(func=cmd_import)
    sh = asub.add_parser("sheet", help="PNG: each asset from six directions with its stored front drawn")
    sh.add_argument("--out", required=True)
    sh.add_argument("--catalog", default="")
    sh.add_argument("--names", nargs="*", default=None, help="categories to show (default: all)")
    sh.add_argument("--px", type=int, default=160, help="view size in pixels")
    sh.set_defaults(func=cmd_sheet)
    sf = asub.add_parser("set-front", help="set a category's front in the file that defines it")
    sf.add_argument("name", help="category name (or a unique label)")
    sf.add_argument("direction", help="+x, -x, +y, -y, +z, -z or 'x,y,z' in the object frame of `assets sheet`")
    sf.add_argument("phrase", help='how to say it, e.g. "the handle side"')
    sf.add_argument("--catalog", default="")
    sf.set_defaults(func=cmd_set_front)
