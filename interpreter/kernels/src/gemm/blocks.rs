//! The tiles of one row block: the AVX2 and portable block (`block_product`), the few-rows
//! path of an actor deciding for a run's agents (`few_rows_product`) and the AVX-512 block
//! (`block_product_wide`).

use super::*;

/// All tiles of one row block: `c_block` starts at the block's first row. Full tiles are
/// updated in place; edge tiles go through a zero-padded copy.
#[allow(clippy::too_many_arguments)]
pub(super) fn block_product(
    packed_a: &[f32],
    panels: &Panels<'_>,
    kc: usize,
    rows: usize,
    n: usize,
    c_block: &mut [f32],
    ldc: usize,
    fma: bool,
    load_c: bool,
) {
    let mut tile = [[0.0f32; NR]; MR];
    let ldb = panels.row_stride;
    for jp in 0..n.div_ceil(NR) {
        let b_panel = panels.panel(jp);
        let j0 = jp * NR;
        let cols = NR.min(n - j0);
        for (ip, a_panel) in packed_a.chunks_exact(MR * kc).enumerate() {
            let i0 = ip * MR;
            let valid = MR.min(rows - i0);
            if cols == NR {
                // Full-width tiles, a last one of fewer rows too (the agents of a run): only
                // the rows that are there are multiplied.
                let c = &mut c_block[i0 * ldc + j0..(i0 + valid - 1) * ldc + j0 + NR];
                micro_kernel(valid, kc, a_panel, b_panel, ldb, c, ldc, fma, load_c);
            } else {
                if load_c {
                    for (r, t) in tile.iter_mut().enumerate().take(valid) {
                        t[..cols].copy_from_slice(&c_block[(i0 + r) * ldc + j0..][..cols]);
                    }
                }
                micro_kernel(
                    MR,
                    kc,
                    a_panel,
                    b_panel,
                    ldb,
                    tile.as_flattened_mut(),
                    NR,
                    fma,
                    load_c,
                );
                for (r, t) in tile.iter().enumerate().take(valid) {
                    c_block[(i0 + r) * ldc + j0..][..cols].copy_from_slice(&t[..cols]);
                }
            }
        }
    }
}

/// Rows up to which [`few_rows_product`] multiplies with AVX2 (its tile of 3 x 32 keeps 12
/// accumulators in flight, where a 3-row slice of the 6 x 16 tile keeps 6: too few to hide
/// the fused multiply-add's latency).
#[cfg(target_arch = "x86_64")]
pub(super) const FEW_ROWS: usize = 3;
/// Columns of [`few_rows_product`]'s tile (four 256-bit vectors).
#[cfg(target_arch = "x86_64")]
pub(super) const FEW_ROWS_COLUMNS: usize = 32;

/// At most [`FEW_ROWS`] rows with the AVX2 kernel, A read in place (the agents of a run through
/// an actor's layer): tiles of `rows` x 32, `a` starting at the block's first row and depth,
/// B's 32-column panels in place or packed beforehand ([`PackedB`]). The sums are the other kernels' (one fused multiply-add per
/// term in increasing `k`), so are the bits.
#[cfg(target_arch = "x86_64")]
#[allow(clippy::too_many_arguments)]
pub(super) fn few_rows_product(
    a: &Mat<'_>,
    panels: &Panels<'_>,
    kc: usize,
    rows: usize,
    n: usize,
    c_block: &mut [f32],
    ldc: usize,
    load_c: bool,
) {
    let ldb = panels.row_stride;
    assert!(
        (1..=FEW_ROWS).contains(&rows)
            && n.is_multiple_of(FEW_ROWS_COLUMNS)
            && a.data.len() > (rows - 1) * a.rs + (kc - 1) * a.cs
            && c_block.len() >= (rows - 1) * ldc + n
    );
    for j0 in (0..n).step_by(FEW_ROWS_COLUMNS) {
        // The 32 columns from `j0` (panels are counted in 16 columns).
        let b_panel = panels.panel(j0 / NR);
        assert!(b_panel.len() >= (kc - 1) * ldb + FEW_ROWS_COLUMNS);
        let (a_ptr, b, c) = (a.data.as_ptr(), b_panel.as_ptr(), c_block[j0..].as_mut_ptr());
        // SAFETY: chosen only with AVX2 and FMA (`Kernel::Avx2Fma`); A holds `rows` rows of
        // `kc` terms, B `kc` rows of the 32 columns from `j0`, C the tile (asserted above).
        unsafe {
            match rows {
                1 => few_rows_kernel_avx2::<1>(kc, a_ptr, a.rs, a.cs, b, ldb, c, ldc, load_c),
                2 => few_rows_kernel_avx2::<2>(kc, a_ptr, a.rs, a.cs, b, ldb, c, ldc, load_c),
                _ => few_rows_kernel_avx2::<3>(kc, a_ptr, a.rs, a.cs, b, ldb, c, ldc, load_c),
            }
        }
    }
}

/// All tiles of one row block with the AVX-512 kernel, reading A in place: `a` starts at the
/// block's first row and depth (element `(i, kk)` at `i * rs + kk * cs`), `packed_b` holds the
/// depth block's panels of [`NR_WIDE`] columns, `c_block` starts at the block's first row.
/// Full tiles are updated in place; tiles over the last columns go through a zero-padded copy.
#[allow(clippy::too_many_arguments)]
pub(super) fn block_product_wide(
    a: &Mat<'_>,
    panels: &Panels<'_>,
    kc: usize,
    rows: usize,
    n: usize,
    c_block: &mut [f32],
    ldc: usize,
    load_c: bool,
) {
    assert!(a.data.len() > (rows - 1) * a.rs + (kc - 1) * a.cs, "A block");
    let mut tile = [[0.0f32; NR_WIDE]; MR_WIDE];
    let ldb = panels.row_stride;
    for jp in 0..n.div_ceil(NR_WIDE) {
        let b_panel = panels.panel(jp);
        let j0 = jp * NR_WIDE;
        let cols = NR_WIDE.min(n - j0);
        // One vector where the panel's second half is padding.
        let vectors = cols.div_ceil(NR);
        for i0 in (0..rows).step_by(MR_WIDE) {
            let valid = MR_WIDE.min(rows - i0);
            let a_tile = &a.data[i0 * a.rs..];
            if cols == vectors * NR {
                let c = &mut c_block[i0 * ldc + j0..(i0 + valid - 1) * ldc + j0 + cols];
                wide_kernel(
                    valid, vectors, kc, a_tile, a.rs, a.cs, b_panel, ldb, c, ldc, load_c,
                );
            } else {
                if load_c {
                    for (r, t) in tile.iter_mut().enumerate().take(valid) {
                        t[..cols].copy_from_slice(&c_block[(i0 + r) * ldc + j0..][..cols]);
                    }
                }
                let t = &mut tile.as_flattened_mut()[..(valid - 1) * NR_WIDE + vectors * NR];
                wide_kernel(
                    valid, vectors, kc, a_tile, a.rs, a.cs, b_panel, ldb, t, NR_WIDE, load_c,
                );
                for (r, t) in tile.iter().enumerate().take(valid) {
                    c_block[(i0 + r) * ldc + j0..][..cols].copy_from_slice(&t[..cols]);
                }
            }
        }
    }
}
