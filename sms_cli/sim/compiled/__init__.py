"""The compiled (numba) side of the simulator: kernels, the compiled loop and plant, and the
numba options every kernel module uses (one place)."""

# cache: compiled once per install (next to the sources); numpy error model: no zero-division
# checks in the hot loops (non-finite states are caught by the divergence checks)
JIT = {"cache": True, "nogil": True, "error_model": "numpy"}
# No numba-level inlining (inline="always"): it lengthened the loop kernels' cold
# compile (flagship warm-up 75.6 -> 53.8 s, analysis kernel 43.5 -> 27.3 s without it), while
# LLVM still inlines small callees: the flagship's step cost did not change (19.4 -> 18.0 us/step).
