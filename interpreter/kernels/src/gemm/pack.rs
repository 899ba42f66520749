//! Packing: B's rows into `k`-major micro-panels and A's row blocks into the AVX2 kernel's
//! panels (copies, never a bit changed).

use rayon::prelude::*;

use super::*;

/// Pack rows `pc..pc + kc` of B into micro-panels of `W` columns, `k`-major, zero-padded;
/// panels are split between rayon's threads when there are several (a copy: no bit changes).
pub(super) fn pack_b<const W: usize>(b: &Mat<'_>, pc: usize, kc: usize, n: usize, out: &mut [f32]) {
    let panel = |(p, panel): (usize, &mut [f32])| pack_b_panel::<W>(b, pc, kc, n, p * W, panel);
    if rayon::current_num_threads() > 1 && n >= 4 * W {
        out.par_chunks_exact_mut(W * kc).enumerate().for_each(panel);
    } else {
        out.chunks_exact_mut(W * kc).enumerate().for_each(panel);
    }
}

/// One micro-panel of [`pack_b`]: columns `j0..j0 + W` of B's rows `pc..pc + kc`.
pub(super) fn pack_b_panel<const W: usize>(
    b: &Mat<'_>,
    pc: usize,
    kc: usize,
    n: usize,
    j0: usize,
    panel: &mut [f32],
) {
    let cols = W.min(n - j0);
    if b.rs == 1 {
        // B is a transposed row-major matrix (W^T): each column is contiguous, so read
        // columns and scatter them into the panel, which stays in L1.
        for jj in 0..cols {
            let column = &b.data[(j0 + jj) * b.cs + pc..][..kc];
            for (kk, &v) in column.iter().enumerate() {
                panel[kk * W + jj] = v;
            }
        }
        if cols < W {
            for row in panel.as_chunks_mut::<W>().0 {
                row[cols..].fill(0.0);
            }
        }
        return;
    }
    for (kk, row) in panel.as_chunks_mut::<W>().0.iter_mut().enumerate() {
        if b.cs == 1 && cols == W {
            // A fixed-size copy (a variable one would call memmove for 16 values).
            let start = (pc + kk) * b.rs + j0;
            *row = b.data[start..start + W].try_into().expect("a panel row");
            continue;
        }
        if b.cs == 1 {
            let start = (pc + kk) * b.rs + j0;
            row[..cols].copy_from_slice(&b.data[start..start + cols]);
        } else {
            for (jj, v) in row[..cols].iter_mut().enumerate() {
                *v = b.at(pc + kk, j0 + jj);
            }
        }
        row[cols..].fill(0.0);
    }
}

/// Pack rows `i0..i0 + rows`, columns `pc..pc + kc` of A into micro-panels of [`MR`] rows,
/// `k`-major, zero-padded.
pub(super) fn pack_a(a: &Mat<'_>, i0: usize, rows: usize, pc: usize, kc: usize, out: &mut [f32]) {
    for (p, panel) in out.chunks_exact_mut(MR * kc).enumerate() {
        let r0 = i0 + p * MR;
        let valid = MR.min(i0 + rows - r0);
        if a.rs == 1 {
            for (kk, col) in panel.as_chunks_mut::<MR>().0.iter_mut().enumerate() {
                let start = (pc + kk) * a.cs + r0;
                if valid == MR {
                    // A fixed-size copy (a variable one would call memmove for 6 values).
                    *col = a.data[start..start + MR].try_into().expect("6 values");
                } else {
                    col[..valid].copy_from_slice(&a.data[start..start + valid]);
                    col[valid..].fill(0.0);
                }
            }
        } else if a.cs == 1 && valid == MR {
            // Row-major A: read the 6 rows side by side, write each k's 6 values at once.
            let rows: [&[f32]; MR] = std::array::from_fn(|r| &a.data[(r0 + r) * a.rs + pc..][..kc]);
            for (kk, col) in panel.as_chunks_mut::<MR>().0.iter_mut().enumerate() {
                *col = std::array::from_fn(|r| rows[r][kk]);
            }
        } else if a.cs == 1 {
            // A row-major last panel (the agents of a run): the rows there, zeros below.
            let rows: [&[f32]; MR] = std::array::from_fn(|r| {
                if r < valid {
                    &a.data[(r0 + r) * a.rs + pc..][..kc]
                } else {
                    &[]
                }
            });
            for (kk, col) in panel.as_chunks_mut::<MR>().0.iter_mut().enumerate() {
                *col = std::array::from_fn(|r| if r < valid { rows[r][kk] } else { 0.0 });
            }
        } else {
            for r in 0..MR {
                if r < valid {
                    let row = &a.data[(r0 + r) * a.rs..];
                    for kk in 0..kc {
                        panel[kk * MR + r] = row[(pc + kk) * a.cs];
                    }
                } else {
                    for kk in 0..kc {
                        panel[kk * MR + r] = 0.0;
                    }
                }
            }
        }
    }
}
