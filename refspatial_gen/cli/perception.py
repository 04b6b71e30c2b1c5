"""`refspatial-gen perception checkpoints|models`: where local perception models go, and random stand-ins.

`checkpoints` lists, per model family, the published checkpoint to place in which folder under the models
folder (`$REFSPATIAL_MODELS`, default ./models); nothing is ever downloaded by refspatial-gen: fetch them
yourself with the hub's tools and save them there. `models --out DIR` writes randomly initialised models
of every family under the same folder names (for plumbing tests and speed benches; `--full` builds the
published architectures' sizes).
"""

from __future__ import annotations

import argparse
import json


def _checkpoints(args: argparse.Namespace) -> int:
    from refspatial_gen.perception.random_models import CHECKPOINTS

    if args.json:
        print(json.dumps(CHECKPOINTS, indent=1, sort_keys=True))
        return 0
    print(f"{'family':<16} {'folder (under $REFSPATIAL_MODELS)':<40} {'published checkpoint':<52} licence")
    for fam, (folder, hub, licence) in CHECKPOINTS.items():
        print(f"{fam:<16} {folder:<40} {hub:<52} {licence}")
    return 0


def _models(args: argparse.Namespace) -> int:
    from refspatial_gen.perception.random_models import BUILDERS, build

    fams = args.families.split(",") if args.families else list(BUILDERS)
    unknown = [f for f in fams if f not in BUILDERS]
    if unknown:
        print(f"unknown families {unknown} (known: {', '.join(BUILDERS)})")
        return 2
    for fam in fams:
        path = build(fam, args.out, full=args.full)
        print(f"{fam:<16} {path}  (random weights)")
    return 0


def register(sub) -> None:
    p = sub.add_parser("perception", help="local perception models: where they go, random stand-ins")
    s = p.add_subparsers(dest="perception_command", required=True)
    c = s.add_parser("checkpoints", help="which published checkpoint goes in which models folder")
    c.add_argument("--json", action="store_true")
    c.set_defaults(func=_checkpoints)
    m = s.add_parser("models", help="write randomly initialised models of every family (tests, benches)")
    m.add_argument("--out", required=True, help="models folder to write into")
    m.add_argument("--families", default=None, help="comma-separated families (default: all)")
    m.add_argument("--full", action="store_true", help="published architectures' sizes (slow, large)")
    m.set_defaults(func=_models)
