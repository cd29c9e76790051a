"""The environment precompute: cube-face geometry (``cubemap``), sharp peaks as lights
(``peaks``), the exact diffuse irradiance (``irradiance``), the ΓL pyramid (``prefilter``, kernel
side ``prefilter_wp``) and the SG mixture fit (``sg_fit``)."""
