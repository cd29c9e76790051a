"""The SG fits of the BRDFs (numpy, scipy): NDF lobe fits (:mod:`~warp_sg.brdf.fitting.fit`), the
measured-BRDF fit (:mod:`~warp_sg.brdf.fitting.measured_fit`) and the generated GGX lobe table
(:mod:`~warp_sg.brdf.fitting.ggx_lobe_table`).
"""
