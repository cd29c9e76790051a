"""PCA of the rows of a matrix lives in the math layer (:mod:`warp_sg.pca`: the measured-BRDF
shadowing basis uses it too); this module re-exports it."""
from warp_sg.pca import PCAResult, pca

__all__ = ["PCAResult", "pca"]
