//! A 4-wide f32 vector on WASM SIMD128 / x86 SSE, scalar elsewhere, for the search kernels.
