"""Asset catalog (assets/catalog.yaml), procedural mesh builders and external mesh import."""

from refspatial_gen.assets.catalog import Catalog, Category, load_catalog
from refspatial_gen.assets.shapes import BUILDERS, AssetGeometry, Part


def build_geometry(cat: Category, dims: dict[str, float], rng) -> AssetGeometry:
    """One instance's geometry: procedural builders take sampled dims; external meshes are fixed."""
    if cat.builder == "external":
        from refspatial_gen.assets.external import build_external

        return build_external(cat)
    return BUILDERS[cat.builder](dims, rng)


__all__ = ["Catalog", "Category", "load_catalog", "BUILDERS", "AssetGeometry", "Part", "build_geometry"]
