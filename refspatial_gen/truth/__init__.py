"""Truth checks: independent evidence (category sizes, what can bear what) a scene is compared with.

See `sizes.py` for the API and docs/quality.md ("Truth checks") for how sources and the graph use it.
"""

from refspatial_gen.truth.sizes import (  # noqa: F401
    IMPLAUSIBLE,
    UNRANGED,
    SizeRange,
    can_bear,
    canonical,
    check_size,
    object_class,
    size_range,
    typical_height,
)
