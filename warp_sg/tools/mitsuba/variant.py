"""Whether Mitsuba 3's LLVM variant can run here (no import of the rest of the peer: the peers and the
bench ask it before they import their scene translation)."""
from __future__ import annotations

#: the oldest system libLLVM the LLVM variants are used with: with LLVM 14 and 15 (Debian 12's default)
#: Dr.Jit's first kernel that takes a minimum aborts the whole process ("Cannot select fminimum"),
#: which no exception reports; 19 (Debian: libllvm19) runs every kernel here
MIN_LLVM = (19, 0, 0)


def llvm_problem(variant: str = "llvm_ad_rgb") -> str | None:
    """None when Mitsuba's LLVM ``variant`` can be set and runs here; else why not, in a few words
    (no libLLVM found, one older than :data:`MIN_LLVM`, or a kernel that fails)."""
    try:
        import drjit as dr
        import mitsuba as mi

        # (asked before the variant is set: Dr.Jit loads the library on import, (-1, -1, -1) without one)
        version = getattr(dr.detail, "llvm_version", lambda: None)()
        if version is not None and tuple(version)[0] <= 0:
            return "no system libLLVM found (Debian: apt install libllvm19; DRJIT_LIBLLVM_PATH names the library)"
        if version is not None and tuple(version) < MIN_LLVM:
            return (f"system libLLVM {'.'.join(map(str, version))} is older than {MIN_LLVM[0]}, with which "
                    f"Mitsuba's kernels abort the process (Debian: apt install libllvm19; DRJIT_LIBLLVM_PATH "
                    f"names the library)")
        mi.set_variant(variant)
        dr.eval(mi.Float([1.0]) * 2.0)
    except Exception as e:  # noqa: BLE001 - a missing or unusable libLLVM, in any exception type
        return f"{type(e).__name__}: {e}"
    return None


__all__ = ["MIN_LLVM", "llvm_problem"]
