"""Math layer, generic numerics: polynomial atan2/asin (``fastmath``), the local orthonormal
frame of a normal (``onb``) and PCA compression (``pca``). Imports the base layer only."""
