"""The on-disk precompute cache is generic and lives in the base layer (:mod:`warp_sg.cache`: the
measured-BRDF fit uses it too); this module re-exports its names."""
from warp_sg.cache import FORMAT_VERSION, cache_dir, content_key, entry_path, fresh_cache, load, load_or_build

__all__ = ["FORMAT_VERSION", "cache_dir", "content_key", "entry_path", "fresh_cache", "load", "load_or_build"]
