//! The f32 numeric kernels of cpmx's MLPs, shared by inference (`cpmx-policy`'s actor) and
//! training (`cpmx-learn`'s networks): one implementation, so a trained actor computes the
//! same bits in `cpmx run` as in `cpmx train`.
//!
//! - `gemm`: the blocked matrix product with fused multiply-adds (AVX-512 12 x 16, AVX2 6 x 16
//!   and portable micro-kernels, chosen at run time, all giving the same bits);
//! - `activation`: tanh (Cephes `tanhf`, 16 or 8 SIMD lanes with the portable function's
//!   bits), relu and elu;
//! - `dense`: a layer `activation(x W^T + b)` over a batch of rows.
//!
//! This crate only computes: shapes and file formats are its callers' concern.

pub mod activation;
pub mod dense;
pub mod gemm;

pub use activation::{Activation, tanh, tanh_portable};
pub use dense::{dense_layer, dense_layer_packed};
pub use gemm::{Mat, PackedB, gemm, gemm_packed};
