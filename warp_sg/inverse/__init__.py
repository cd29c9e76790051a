"""Tools layer: inverse rendering — materials, textures and lighting recovered from photographs of a
scene whose geometry is known, through the renderer's gradients (``warp-sg fit``, ``ws.fit``:
:mod:`warp_sg.inverse.fit`; the photographs :mod:`~warp_sg.inverse.views`, the free parameters
:mod:`~warp_sg.inverse.free`, the environment's SG basis :mod:`~warp_sg.inverse.env_basis`, Adam
:mod:`~warp_sg.inverse.adam`, the written scene :mod:`~warp_sg.inverse.outputs`). No library module
imports it."""
