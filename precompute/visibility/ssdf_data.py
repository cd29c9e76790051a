r"""The SSDF record of a mesh (:class:`SSDFData`, paper eq. 23–24) and the memory budgets it is kept
within: the PCA form, the uncompressed maps where they fit, the occluder cones and the
representatives' blend. Built by :func:`precompute.visibility.ssdf.ssdf_for_mesh` (and
:func:`precompute.visibility.ssdf_groups.ssdf_for_groups`), which also re-exports these names.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import warp as wp

from warp_sg.core.device import resolve_device
from warp_sg.core.errors import InputError
from warp_sg.numeric.pca import DeferredPCA, PCAResult

#: the default ray resolution (``ssdf_for_mesh``: 2 × the map resolution)
DEFAULT_RAY_RESOLUTION = 64


@dataclass
class SSDFData:
    """PCA-compressed SSDFs of a mesh (eq. 24): ``SSDF_x ≈ mean + Σ_j weights[x, j] basis[j]``.

    ``mean`` (R, R), ``basis`` (NV, R, R), ``weights`` (V, NV), all float32, radians, on the
    concentric map of :mod:`precompute.visibility.ssdf_wp`. ``pca_rms_error[k]`` is the RMS reconstruction
    error (radians, over all vertices and texels) with ``k`` terms, k = 0..NV. They are read from
    ``pca`` (:class:`warp_sg.numeric.pca.DeferredPCA`): where the uncompressed ``maps`` are kept,
    the PCA is computed from them the first time one of them is read, which the renderer never
    does while the maps fit its budget (:meth:`device_arrays`).
    """

    resolution: int
    pca: DeferredPCA
    ray_resolution: int = DEFAULT_RAY_RESOLUTION
    key: str = ""
    #: (V, 4) per-vertex occluder cones (:func:`precompute.visibility.occluder_cone.occluder_cones`); empty:
    #: unknown (no lookup is skipped)
    cones: np.ndarray = field(default_factory=lambda: np.zeros((0, 4), np.float32))
    #: ``{stage: (wall s, CPU s)}`` of the build (``bvh``, ``rays``, ``ssdf_fit``, ``pca``, ``cones``;
    #: :class:`warp_sg.core.stage_clock.StageClock`) and counts (``rays_cast``, ``uniform_vertices``: ints);
    #: empty when the data came from the cache
    stats: dict = field(default_factory=dict)
    #: (V,) int32: the vertex whose ray-cast map each vertex's map was transferred from
    #: (:mod:`precompute.visibility.representatives`); empty: every vertex has its own
    representative: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    #: (V, k) int32 / float32: the representatives each vertex's map is blended from and their
    #: weights (``build_at_representatives``; a representative: itself, 1); empty without
    blend_index: np.ndarray = field(default_factory=lambda: np.zeros((0, 1), np.int32))
    blend_weight: np.ndarray = field(default_factory=lambda: np.zeros((0, 1), np.float32))
    #: (V, R²) float32 uncompressed maps, kept within :func:`decompress_budget`; empty: PCA form only
    maps: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), np.float32))

    @classmethod
    def from_entry(cls, data: dict, *, resolution: int, pca_terms: int, **kw) -> "SSDFData":
        """From a cache entry: the PCA form (``mean``, ``basis``, ``weights``, ``pca_rms_error``)
        when it holds one, else the ``maps`` it is computed from on first use (``pca_terms`` terms)."""
        R = int(resolution)
        maps = np.asarray(data.get("maps", np.zeros((0, 0))), np.float32)
        if "mean" in data:
            nv = int(np.shape(data["basis"])[0])
            p = DeferredPCA.of(PCAResult(np.asarray(data["mean"], np.float32).reshape(R * R),
                                         np.asarray(data["basis"], np.float32).reshape(nv, R * R),
                                         np.asarray(data["weights"], np.float32),
                                         np.asarray(data["pca_rms_error"])))
        else:
            p = DeferredPCA(maps, int(pca_terms))
        return cls(resolution=R, pca=p, maps=maps, cones=np.asarray(data["cones"], np.float32),
                   representative=np.asarray(data.get("representative", np.zeros(0)), np.int32),
                   blend_index=np.asarray(data.get("blend_index", np.zeros((0, 1))), np.int32),
                   blend_weight=np.asarray(data.get("blend_weight", np.zeros((0, 1))), np.float32), **kw)

    @property
    def mean(self) -> np.ndarray:
        return self.pca.result().mean.reshape(self.resolution, self.resolution)

    @property
    def basis(self) -> np.ndarray:
        return self.pca.result().basis.reshape(-1, self.resolution, self.resolution)

    @property
    def weights(self) -> np.ndarray:
        return self.pca.result().weights

    @property
    def pca_rms_error(self) -> np.ndarray:
        return self.pca.result().rms_error

    @property
    def n_vertices(self) -> int:
        return self.pca.n_rows

    def blend_arrays(self, device):
        """``(representative ids, blend_index, blend_weight)`` as device arrays (kept per device), or
        None when every vertex has its own map."""
        if not len(self.blend_index):
            return None
        memo = self.__dict__.setdefault("_blend_memo", {})
        if str(device) not in memo:
            memo[str(device)] = (wp.array(np.unique(self.representative).astype(np.int32), dtype=int, device=device),
                                 wp.array(self.blend_index, dtype=int, device=device),
                                 wp.array(self.blend_weight, dtype=float, device=device))
        return memo[str(device)]

    @property
    def pca_terms(self) -> int:
        return self.pca.n_terms

    def reconstruct(self, vertex_ids=None) -> np.ndarray:
        """Reconstructed SSDFs ``(n, R, R)`` of ``vertex_ids`` (default: all vertices)."""
        w = self.weights if vertex_ids is None else self.weights[np.asarray(vertex_ids)]
        R = self.resolution
        return (self.mean.reshape(1, -1) + w @ self.basis.reshape(self.pca_terms, -1)).reshape(-1, R, R)

    def device_arrays(self, device="cpu", decompress_bytes: int = 0):
        """``(mean wp.array2d (R, R), basis wp.array3d (R, R, NV), weights wp.array2d (V, NV))`` for
        :mod:`precompute.visibility.ssdf_wp`; the basis is texel-major on the device (a bilinear tap reads NV
        contiguous floats).

        Decompressed form, when the reconstructed maps take at most ``decompress_bytes``
        (``V·R²`` float32): ``mean`` zeros, ``basis`` of shape (R, R, 0) and ``weights`` (V, R²),
        each vertex's uncompressed map where kept (``maps``), else ``mean + Σ_j w_j basis_j``
        (``reconstruct``), row-major. A lookup then reads 4 texels per vertex instead of 4·(NV + 1)
        values and NV weights (``ssdf_wp._ssdf_combo`` takes either form)."""
        device = resolve_device(device)
        R, V = self.resolution, self.n_vertices
        if V * R * R * 4 <= int(decompress_bytes):
            maps = self.maps if self.maps.shape == (V, R * R) else self.reconstruct().reshape(V, R * R)
            return (wp.zeros((R, R), dtype=float, device=device), wp.zeros((R, R, 0), dtype=float, device=device),
                    wp.array(maps.astype(np.float32), dtype=float, device=device))
        return (wp.array(self.mean, dtype=float, device=device),
                wp.array(np.ascontiguousarray(np.moveaxis(self.basis, 0, -1)), dtype=float, device=device),
                wp.array(self.weights, dtype=float, device=device))


def budget_mib(variable: str, default: str) -> int:
    """Bytes of the MiB budget in environment variable ``variable`` (``default`` when unset); a
    value that is not a number is an :class:`InputError` naming the variable."""
    import os

    raw = os.environ.get(variable, default)
    try:
        mb = float(raw)
    except ValueError:
        raise InputError(f"{variable} must be a number of MiB, got {raw!r}", where=variable) from None
    return max(int(mb * (1 << 20)), 0)


def decompress_budget() -> int:
    """Bytes the renderer may spend on decompressed SSDF maps (``SSDFData.device_arrays``):
    ``WARP_SG_SSDF_DECOMPRESS_MB`` (default 256 MiB; 0 keeps the PCA form). 50 k vertices at the
    default 32² maps take 205 MB; within it the uncompressed maps are kept (``SSDFData.maps``)."""
    return budget_mib("WARP_SG_SSDF_DECOMPRESS_MB", "256")


def memory_budget() -> int:
    """Bytes of uncompressed SSDFs ``ssdf_for_mesh`` keeps in memory (``WARP_SG_SSDF_MEMORY_MB``,
    default 1024 MiB); beyond, the rows go to a temporary file in the cache folder and PCA and the
    occluder cones read them back in chunks (out of core: 1 M vertices at 32² are 4 GiB on disk)."""
    return budget_mib("WARP_SG_SSDF_MEMORY_MB", "1024")


__all__ = ["SSDFData", "budget_mib", "decompress_budget", "memory_budget", "DEFAULT_RAY_RESOLUTION"]
