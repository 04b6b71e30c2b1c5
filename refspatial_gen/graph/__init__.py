"""Scene graph: a metric 3D graph per frame — nodes with attributes, unique referring phrases and answer
points; supports; the 31 spatial relations (plus on/under/next-to/object-frame directions) as facts with
values and margins; free-space regions for placement.

Public API:
  build_graph(frame, config=None) -> SceneGraph
  query.GraphIndex(graph, frame=None)      look up facts (mirrors, derived close/far) without geometry
  relations.REGISTRY / relations.listing() the relation registry
  resolve.resolve_phrase(phrase, frame_or_graph) -> list[int]   independent phrase resolver
  freespace.check_free_point(frame, graph, region, point=None) -> list[str]   problems, [] when valid
"""

from refspatial_gen.graph.builder import build_graph, geometry

__all__ = ["build_graph", "geometry"]
