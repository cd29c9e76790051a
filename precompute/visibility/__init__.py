"""The visibility precompute: per-vertex hemisphere ray queries (``rays``), adaptive ray maps,
mesh refinement where the visibility changes (``refine``), SSDFs (``ssdf``, lookups ``ssdf_wp``)
and the occluder cones; ``reference_checks`` holds the tests' brute-force references."""
