//! The register-blocked micro-kernels: AVX2 (6 x 16, and 1-3 x 32 for few rows), AVX-512
//! (up to 12 x 32) and the portable reference, all one fused multiply-add per term in
//! increasing `k` (the module `gemm` says why that gives the same bits).

use super::*;

/// # Safety
/// The CPU must support AVX2 and FMA; `a` must be valid at `r * rs + kk * cs` for `r < R`,
/// `kk < kc`, `b` at `kk * ldb + j` for `j < 32`, and `c` at `r * ldc + j`, `j < 32`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[allow(clippy::too_many_arguments)]
pub(super) unsafe fn few_rows_kernel_avx2<const R: usize>(
    kc: usize,
    a: *const f32,
    rs: usize,
    cs: usize,
    b: *const f32,
    ldb: usize,
    c: *mut f32,
    ldc: usize,
    load_c: bool,
) {
    use std::arch::x86_64::*;
    const V: usize = FEW_ROWS_COLUMNS / 8;
    let mut acc = [[_mm256_setzero_ps(); V]; R];
    if load_c {
        for (r, acc_r) in acc.iter_mut().enumerate() {
            for (v, acc_rv) in acc_r.iter_mut().enumerate() {
                // SAFETY: within the tile (caller's guarantee).
                *acc_rv = unsafe { _mm256_loadu_ps(c.add(r * ldc + v * 8)) };
            }
        }
    }
    for kk in 0..kc {
        // SAFETY: `kk < kc`, `r < R`, `v < V`: within the operands (caller's guarantee).
        unsafe {
            // A's R values broadcast once, then B's vectors one at a time: 3 x 4 accumulators,
            // 3 broadcasts and one vector of B fill AVX2's 16 registers exactly (holding all
            // four vectors of B's row needs 17, and the accumulators spill to the stack).
            let a_k = a.add(kk * cs);
            let a_r: [__m256; R] = std::array::from_fn(|r| _mm256_broadcast_ss(&*a_k.add(r * rs)));
            // Column-major over the accumulators (`acc[r][v]`, v outer): indices, not iterators.
            #[allow(clippy::needless_range_loop)]
            for v in 0..V {
                let b_kv = _mm256_loadu_ps(b.add(kk * ldb + v * 8));
                for r in 0..R {
                    acc[r][v] = _mm256_fmadd_ps(a_r[r], b_kv, acc[r][v]);
                }
            }
        }
    }
    for (r, acc_r) in acc.iter().enumerate() {
        for (v, acc_rv) in acc_r.iter().enumerate() {
            // SAFETY: within the tile (caller's guarantee).
            unsafe { _mm256_storeu_ps(c.add(r * ldc + v * 8), *acc_rv) };
        }
    }
}

/// `C_tile += A_panel B_panel` over `kc` terms (`C_tile = ...` when `load_c` is false) for the
/// first `rows` (1 to [`MR`]) rows of the A panel; B's row `kk` is `b[kk * ldb..][..NR]`; `c`
/// holds the `rows x NR` tile with row stride `ldc` (`c[r * ldc + j]`).
#[inline]
#[allow(clippy::too_many_arguments)]
pub(super) fn micro_kernel(
    rows: usize,
    kc: usize,
    a: &[f32],
    b: &[f32],
    ldb: usize,
    c: &mut [f32],
    ldc: usize,
    fma: bool,
    load_c: bool,
) {
    assert!(
        (1..=MR).contains(&rows)
            && a.len() >= kc * MR
            && b.len() >= (kc - 1) * ldb + NR
            && c.len() > (rows - 1) * ldc + NR - 1
    );
    #[cfg(target_arch = "x86_64")]
    if fma {
        let (a, b, c) = (a.as_ptr(), b.as_ptr(), c.as_mut_ptr());
        // SAFETY: the CPU has AVX2 and FMA (checked by `has_fma`); the panels hold `kc` rows
        // and `c` the tile's `rows` rows (asserted above).
        unsafe {
            match rows {
                1 => micro_kernel_avx2::<1>(kc, a, b, ldb, c, ldc, load_c),
                2 => micro_kernel_avx2::<2>(kc, a, b, ldb, c, ldc, load_c),
                3 => micro_kernel_avx2::<3>(kc, a, b, ldb, c, ldc, load_c),
                4 => micro_kernel_avx2::<4>(kc, a, b, ldb, c, ldc, load_c),
                5 => micro_kernel_avx2::<5>(kc, a, b, ldb, c, ldc, load_c),
                _ => micro_kernel_avx2::<MR>(kc, a, b, ldb, c, ldc, load_c),
            }
        }
        return;
    }
    let _ = fma;
    micro_kernel_portable(rows, kc, a, b, ldb, c, ldc, load_c);
}

/// The AVX-512 tile of `rows` (1 to [`MR_WIDE`]) rows and `vectors` (1 or 2) times 16
/// columns: `C_tile (+)= A_tile B_panel` over `kc` terms, A element `(r, kk)` at
/// `a[r * rs + kk * cs]`, B row `kk` at `b[kk * ldb..]`, C element `(r, j)` at
/// `c[r * ldc + j]`.
#[allow(clippy::too_many_arguments)]
pub(super) fn wide_kernel(
    rows: usize,
    vectors: usize,
    kc: usize,
    a: &[f32],
    rs: usize,
    cs: usize,
    b: &[f32],
    ldb: usize,
    c: &mut [f32],
    ldc: usize,
    load_c: bool,
) {
    assert!(
        (1..=MR_WIDE).contains(&rows)
            && (1..=2).contains(&vectors)
            && a.len() > (rows - 1) * rs + (kc - 1) * cs
            && b.len() >= (kc - 1) * ldb + vectors * NR
            && c.len() >= (rows - 1) * ldc + vectors * NR
    );
    #[cfg(target_arch = "x86_64")]
    {
        let (a, b, c) = (a.as_ptr(), b.as_ptr(), c.as_mut_ptr());
        macro_rules! tile {
            ($($r:literal)*) => {
                match (rows, vectors) {
                    // SAFETY: the kernel is only chosen when the CPU has AVX-512F
                    // (`Kernel::available`); the operands hold the tile (asserted above).
                    $(
                        ($r, 1) => unsafe { micro_kernel_avx512::<$r, 1>(kc, a, rs, cs, b, ldb, c, ldc, load_c) },
                        ($r, _) => unsafe { micro_kernel_avx512::<$r, 2>(kc, a, rs, cs, b, ldb, c, ldc, load_c) },
                    )*
                    _ => unreachable!("1 to 12 rows"),
                }
            };
        }
        tile!(1 2 3 4 5 6 7 8 9 10 11 12);
    }
    #[cfg(not(target_arch = "x86_64"))]
    unreachable!("the AVX-512 kernel is only chosen on x86_64");
}

/// # Safety
/// The CPU must support AVX-512F; `a` must be valid at `r * rs + kk * cs` for `r < R`,
/// `kk < kc`, `b` at `kk * ldb + j`, and `c` at `r * ldc + j`, `r < R`, `j < 16 V`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[allow(clippy::too_many_arguments)]
pub(super) unsafe fn micro_kernel_avx512<const R: usize, const V: usize>(
    kc: usize,
    a: *const f32,
    rs: usize,
    cs: usize,
    b: *const f32,
    ldb: usize,
    c: *mut f32,
    ldc: usize,
    load_c: bool,
) {
    use std::arch::x86_64::*;
    let mut acc = [[_mm512_setzero_ps(); V]; R];
    if load_c {
        for (r, acc_r) in acc.iter_mut().enumerate() {
            for (v, acc_rv) in acc_r.iter_mut().enumerate() {
                // SAFETY: within the tile (caller's guarantee).
                *acc_rv = unsafe { _mm512_loadu_ps(c.add(r * ldc + v * NR)) };
            }
        }
    }
    for kk in 0..kc {
        // SAFETY: `kk < kc`, `r < R`, `v < V`: within the operands (caller's guarantee).
        unsafe {
            let b_k: [__m512; V] = std::array::from_fn(|v| _mm512_loadu_ps(b.add(kk * ldb + v * NR)));
            let a_k = a.add(kk * cs);
            for (r, acc_r) in acc.iter_mut().enumerate() {
                let a_rk = _mm512_set1_ps(*a_k.add(r * rs));
                for (acc_rv, &b_kv) in acc_r.iter_mut().zip(&b_k) {
                    *acc_rv = _mm512_fmadd_ps(a_rk, b_kv, *acc_rv);
                }
            }
        }
    }
    for (r, acc_r) in acc.iter().enumerate() {
        for (v, acc_rv) in acc_r.iter().enumerate() {
            // SAFETY: within the tile (caller's guarantee).
            unsafe { _mm512_storeu_ps(c.add(r * ldc + v * NR), *acc_rv) };
        }
    }
}

/// The reference micro-kernel: the same fused operations in the same order as the AVX2 one.
#[allow(clippy::too_many_arguments)]
pub(crate) fn micro_kernel_portable(
    rows: usize,
    kc: usize,
    a: &[f32],
    b: &[f32],
    ldb: usize,
    c: &mut [f32],
    ldc: usize,
    load_c: bool,
) {
    let mut tile = [[0.0f32; NR]; MR];
    let tile = &mut tile[..rows];
    if load_c {
        for (r, t) in tile.iter_mut().enumerate() {
            t.copy_from_slice(&c[r * ldc..r * ldc + NR]);
        }
    }
    for kk in 0..kc {
        let b_row = &b[kk * ldb..kk * ldb + NR];
        for (r, t) in tile.iter_mut().enumerate() {
            let a_rk = a[kk * MR + r];
            for (t_rc, &b_kc) in t.iter_mut().zip(b_row) {
                *t_rc = a_rk.mul_add(b_kc, *t_rc);
            }
        }
    }
    for (r, t) in tile.iter().enumerate() {
        c[r * ldc..r * ldc + NR].copy_from_slice(t);
    }
}

/// # Safety
/// The CPU must support AVX2 and FMA; `R <= MR`; `a` must be valid for `kc * MR` values, `b`
/// at `kk * ldb + j` for `kk < kc`, `j < NR`, and `c` for the tile `c[r * ldc + j]`, `r < R`,
/// `j < NR`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn micro_kernel_avx2<const R: usize>(
    kc: usize,
    a: *const f32,
    b: *const f32,
    ldb: usize,
    c: *mut f32,
    ldc: usize,
    load_c: bool,
) {
    use std::arch::x86_64::*;
    let mut acc = [[_mm256_setzero_ps(); 2]; R];
    for (r, acc_r) in acc.iter_mut().enumerate().filter(|_| load_c) {
        // SAFETY: within the tile (caller's guarantee).
        unsafe {
            acc_r[0] = _mm256_loadu_ps(c.add(r * ldc));
            acc_r[1] = _mm256_loadu_ps(c.add(r * ldc + 8));
        }
    }
    for kk in 0..kc {
        // SAFETY: `kk < kc`, within the panels (caller's guarantee).
        unsafe {
            let b0 = _mm256_loadu_ps(b.add(kk * ldb));
            let b1 = _mm256_loadu_ps(b.add(kk * ldb + 8));
            let a_k = a.add(kk * MR);
            for (r, acc_r) in acc.iter_mut().enumerate() {
                let a_rk = _mm256_broadcast_ss(&*a_k.add(r));
                acc_r[0] = _mm256_fmadd_ps(a_rk, b0, acc_r[0]);
                acc_r[1] = _mm256_fmadd_ps(a_rk, b1, acc_r[1]);
            }
        }
    }
    for (r, acc_r) in acc.iter().enumerate() {
        // SAFETY: within the tile (caller's guarantee).
        unsafe {
            _mm256_storeu_ps(c.add(r * ldc), acc_r[0]);
            _mm256_storeu_ps(c.add(r * ldc + 8), acc_r[1]);
        }
    }
}
