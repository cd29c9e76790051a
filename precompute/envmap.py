"""Equirectangular environment maps — the map convention, lookups, rotation, loading and the
procedural sky live in the scene layer (:mod:`warp_sg.envmap`: lights and scenes read maps without
importing an engine); this module re-exports every name, the ``@wp.func`` lookups included (the
same objects, so kernels may use either)."""
from warp_sg.envmap import *  # noqa: F401,F403 - the re-export is this module's purpose
from warp_sg.envmap import PI, TWO_PI, __all__  # noqa: F401
