"""The compiled (numba) side of the simulator: kernels, the compiled loop and plant, and the
numba options every kernel module uses (one place)."""

# cache: compiled once per install (next to the sources); numpy error model: no zero-division
# checks in the hot loops (non-finite states are caught by the divergence checks)
JIT = {"cache": True, "nogil": True, "error_model": "numpy"}
# for helpers called in the innermost loop, and ABA in the plant step: no call boundary (a numba call with
# many array arguments costs 0.1-0.4 us, as much as a small helper's work; ABA as a plain call costs the
# compiled loop on Basilisk's scenario 5.9 -> 7.5 us per step). The rest are plain calls: inlining
# everything lengthens the cold compile for no speed.
HOT = dict(JIT, inline="always")
