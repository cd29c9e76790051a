"""Render layer: the stateful :class:`~warp_sg.renderer.renderer.Renderer` (``ws.Renderer``) and
``ws.render`` — its resources (what the precompute produces), the kernel-variant choice, the frame
paths, the environment set-up, antialiasing, the cost checks and the progressive shadows."""
