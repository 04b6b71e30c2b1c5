"""`refspatial-gen relations [--json]`: list the relation registry."""

from __future__ import annotations

import argparse
import json


def _relations(args: argparse.Namespace) -> int:
    from refspatial_gen.graph.relations import SPEC_31, listing

    rows = listing()
    if args.json:
        print(json.dumps({"count": len(rows), "spec_31": len(SPEC_31), "relations": rows}, indent=1, sort_keys=True))
        return 0
    print(f"{len(rows)} relations ({len(SPEC_31)} from the spec, * = extra)")
    for r in rows:
        mark = " " if r["in_31"] else "*"
        print(
            f"{mark} {r['id']:<20} {r['frame']:<5} arity {r['arity']}  [{', '.join(r['sources'])}]  {r['definition']}"
        )
    return 0


def register(sub) -> None:
    p = sub.add_parser("relations", help="list the spatial relations the scene graph evaluates")
    p.add_argument("--json", action="store_true", help="machine-readable listing")
    p.set_defaults(func=_relations)
