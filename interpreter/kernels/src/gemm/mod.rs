//! The f32 matrix product of every MLP in cpmx: `C (+)= op(A) op(B)` over strided operands, B packed
//! BLIS-style into `k`-major panels and multiplied by register-blocked micro-kernels with fused
//! multiply-adds: 12 x 32 tiles with AVX-512 (24 of the 32 vector registers accumulate, enough
//! to keep two 512-bit FMA units busy; A read in place through its strides: no packing of A;
//! B in panels of 32 columns), 6 x 16 with AVX2 and FMA (A packed), and a portable kernel.
//! B is packed whenever its panels are used by more than one tile: read in place, a row-major B's
//! rows lie a power of two apart and fall into a few L1 sets, so a panel does not stay in L1
//! between tiles (measured on an Intel core with two AVX-512 FMA units: 64-72 GFLOP/s in place
//! with 12 x 16 tiles, 145-155 packed with 12 x 32, of a 175 GFLOP/s peak). A product of at most
//! one tile of rows (an actor deciding for the agents of a run) uses each element of B once:
//! packing would copy every weight to read it once more (in `cpmx run`, 20 % of a sim run's time
//! went to packing), so a row-major B whose panels are all full is read in place there, with
//! AVX2 in tiles of up to 3 x 32 (`few_rows_product`: 12 accumulators in flight) and otherwise
//! in the usual kernels' last tile of 1 to 6 (12) rows.
//!
//! Every element of C is one running sum over `k` in increasing order, one fused
//! multiply-add per term, starting from C's previous value (or 0); a value stored between
//! depth blocks is the exact running sum. The kernels (chosen at run time) and the portable
//! kernel (`f32::mul_add`, the same correctly rounded operation) therefore give the same bits,
//! and so does any split of the rows between rayon threads: results never depend on the CPU's
//! vector extensions, the path or the thread count.

use std::cell::{Cell, RefCell};

use rayon::prelude::*;

mod blocks;
mod pack;
#[cfg(test)]
mod tests;
mod tiles;

use blocks::*;
use pack::*;
use tiles::*;

/// Rows of the AVX2 and portable micro-kernels' tile.
pub const MR: usize = 6;
/// Rows of the AVX-512 micro-kernel's tile.
pub const MR_WIDE: usize = 12;
/// Columns of the AVX2 and portable micro-kernels' tile (two 256-bit vectors), and of one
/// 512-bit vector.
pub const NR: usize = 16;
/// Columns of the AVX-512 micro-kernel's tile and of its B panels (two 512-bit vectors; a
/// last panel of at most [`NR`] columns is multiplied with one).
pub const NR_WIDE: usize = 32;
/// Depth of one packed block (a 6 x 256 A micro-panel and a 256 x 16 B micro-panel fit L1).
const KC: usize = 256;
/// Largest row block packed at once (fits L2 together with the packed B block).
const MC_MAX: usize = 120;

/// A read-only matrix view: element `(i, j)` is `data[i * rs + j * cs]`.
#[derive(Debug, Clone, Copy)]
pub struct Mat<'a> {
    /// The elements.
    pub data: &'a [f32],
    /// Row stride.
    pub rs: usize,
    /// Column stride.
    pub cs: usize,
}

impl<'a> Mat<'a> {
    /// A row-major matrix with `cols` columns.
    pub fn rows(data: &'a [f32], cols: usize) -> Self {
        Mat {
            data,
            rs: cols,
            cs: 1,
        }
    }
    /// The transpose of a row-major matrix with `cols` columns.
    pub fn transposed(data: &'a [f32], cols: usize) -> Self {
        Mat {
            data,
            rs: 1,
            cs: cols,
        }
    }
    #[inline(always)]
    fn at(&self, i: usize, j: usize) -> f32 {
        self.data[i * self.rs + j * self.cs]
    }
}

thread_local! {
    /// Per-thread packing buffer for blocks of A.
    static PACK_A: RefCell<Vec<f32>> = const { RefCell::new(Vec::new()) };
    /// The calling thread's packing buffer for B: taken for the length of a product and put
    /// back (a product that starts on the same thread meanwhile, stolen by rayon, finds it
    /// empty and allocates its own), so products after the first allocate nothing.
    static PACK_B: Cell<Vec<f32>> = const { Cell::new(Vec::new()) };
}

/// `C = op(A) op(B) + (accumulate ? C : 0)` with `A` `m x k`, `B` `k x n`, and `C` row-major
/// `m x n` with row stride `ldc`. Row blocks run on rayon's current pool; results do not
/// depend on it (see the module documentation).
#[allow(clippy::too_many_arguments)]
pub fn gemm(
    m: usize,
    n: usize,
    k: usize,
    a: Mat<'_>,
    b: Mat<'_>,
    c: &mut [f32],
    ldc: usize,
    accumulate: bool,
) {
    gemm_with(Kernel::detect(), m, n, k, a, b, c, ldc, accumulate);
}

/// The micro-kernels, fastest first.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kernel {
    /// 12 x 32 tiles in 512-bit registers, A read in place (`avx512f`).
    Avx512,
    /// 6 x 16 tiles in 256-bit registers from packed A (`avx2` and `fma`).
    Avx2Fma,
    /// `f32::mul_add` over packed A.
    Portable,
}

impl Kernel {
    /// The fastest kernel this CPU runs.
    pub fn detect() -> Kernel {
        Self::available().into_iter().next().unwrap_or(Kernel::Portable)
    }

    /// Every kernel this CPU runs, fastest first (the portable one always).
    pub fn available() -> Vec<Kernel> {
        let mut out = Vec::new();
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                out.push(Kernel::Avx512);
            }
            if has_fma() {
                out.push(Kernel::Avx2Fma);
            }
        }
        out.push(Kernel::Portable);
        out
    }

    /// Rows of one tile.
    fn tile_rows(self) -> usize {
        match self {
            Kernel::Avx512 => MR_WIDE,
            Kernel::Avx2Fma | Kernel::Portable => MR,
        }
    }

    /// Columns of one packed B panel.
    fn panel_columns(self) -> usize {
        match self {
            Kernel::Avx512 => NR_WIDE,
            Kernel::Avx2Fma | Kernel::Portable => NR,
        }
    }
}

/// [`gemm`] with the given kernel (which the CPU must support; [`Kernel::available`]).
#[allow(clippy::too_many_arguments)]
pub fn gemm_with(
    kernel: Kernel,
    m: usize,
    n: usize,
    k: usize,
    a: Mat<'_>,
    b: Mat<'_>,
    c: &mut [f32],
    ldc: usize,
    accumulate: bool,
) {
    product(kernel, m, n, k, a, BSource::View(b), c, ldc, accumulate);
}

/// The product of [`gemm_with`] and [`gemm_packed`].
#[allow(clippy::too_many_arguments)]
fn product(
    kernel: Kernel,
    m: usize,
    n: usize,
    k: usize,
    a: Mat<'_>,
    b: BSource<'_>,
    c: &mut [f32],
    ldc: usize,
    accumulate: bool,
) {
    if m == 0 || n == 0 {
        return;
    }
    assert!(c.len() >= (m - 1) * ldc + n, "C too small");
    if k == 0 {
        if !accumulate {
            for row in c.chunks_mut(ldc).take(m) {
                row[..n].fill(0.0);
            }
        }
        return;
    }
    let b_fits = match b {
        BSource::View(b) => b.data.len() > (k - 1) * b.rs + (n - 1) * b.cs,
        BSource::Packed(p) => p.k == k && p.n == n,
    };
    assert!(
        a.data.len() > (m - 1) * a.rs + (k - 1) * a.cs && b_fits,
        "A or B too small"
    );
    let width = kernel.panel_columns();
    let n_panels = n.div_ceil(width);
    let tile = kernel.tile_rows();
    // One tile of rows reads each element of B once: read a row-major B in place when every
    // panel is full (the kernels load whole panel rows).
    let in_place = matches!(b, BSource::View(b) if m <= tile && b.cs == 1 && n.is_multiple_of(width));
    let mut packed_b = PACK_B.take();
    if matches!(b, BSource::View(_)) && !in_place {
        packed_b.resize(n_panels * width * KC.min(k), 0.0);
    }
    // Row blocks: at least two per thread when there are enough rows.
    let threads = rayon::current_num_threads();
    let blocks = m.div_ceil(MC_MAX).max((2 * threads).min(m.div_ceil(4 * tile)));
    let mc = m.div_ceil(blocks).div_ceil(tile) * tile;
    for pc in (0..k).step_by(KC) {
        let kc = KC.min(k - pc);
        // Without `accumulate`, the first depth block starts every tile from zero instead of
        // loading C (the same sums as zeroing C first, without the pass over C).
        let load_c = accumulate || pc > 0;
        let panels = match b {
            BSource::Packed(p) => Panels {
                data: &p.data[pc * NR_WIDE..],
                row_stride: NR_WIDE,
                panel_stride: NR_WIDE * k,
                halves: NR_WIDE / width,
            },
            BSource::View(b) if in_place => Panels {
                data: &b.data[pc * b.rs..],
                row_stride: b.rs,
                panel_stride: width,
                halves: 1,
            },
            BSource::View(b) => {
                let packed_b = &mut packed_b[..n_panels * width * kc];
                if kernel == Kernel::Avx512 {
                    pack_b::<NR_WIDE>(&b, pc, kc, n, packed_b);
                } else {
                    pack_b::<NR>(&b, pc, kc, n, packed_b);
                }
                Panels {
                    data: &*packed_b,
                    row_stride: width,
                    panel_stride: width * kc,
                    halves: 1,
                }
            }
        };
        // Panels whose 32 columns are all B's, as the few-rows kernel reads them.
        let whole_panels = (in_place || matches!(b, BSource::Packed(_))) && n.is_multiple_of(NR_WIDE);
        let c_rows = &mut c[..(m - 1) * ldc + n];
        let work = |(block, c_block): (usize, &mut [f32])| {
            let i0 = block * mc;
            let rows = mc.min(m - i0);
            if kernel == Kernel::Avx512 {
                let a_block = Mat {
                    data: &a.data[i0 * a.rs + pc * a.cs..],
                    ..a
                };
                block_product_wide(&a_block, &panels, kc, rows, n, c_block, ldc, load_c);
                return;
            }
            #[cfg(target_arch = "x86_64")]
            if kernel == Kernel::Avx2Fma && whole_panels && rows <= FEW_ROWS {
                let a_block = Mat {
                    data: &a.data[i0 * a.rs + pc * a.cs..],
                    ..a
                };
                few_rows_product(&a_block, &panels, kc, rows, n, c_block, ldc, load_c);
                return;
            }
            PACK_A.with_borrow_mut(|packed_a| {
                packed_a.resize(rows.div_ceil(MR) * MR * kc, 0.0);
                pack_a(&a, i0, rows, pc, kc, packed_a);
                let fma = kernel == Kernel::Avx2Fma;
                block_product(packed_a, &panels, kc, rows, n, c_block, ldc, fma, load_c);
            });
        };
        if threads > 1 && blocks > 1 {
            c_rows.par_chunks_mut(mc * ldc).enumerate().for_each(work);
        } else {
            c_rows.chunks_mut(mc * ldc).enumerate().for_each(work);
        }
    }
    PACK_B.set(packed_b);
}

/// B's panels for one depth block, packed or in place: panel `jp`'s row `kk` (its `W` columns)
/// starts at `data[jp * panel_stride + kk * row_stride]`. A [`PackedB`]'s 32-column panels
/// serve the 16-column kernels as two halves each (`halves`: 2).
#[derive(Debug, Clone, Copy)]
struct Panels<'a> {
    data: &'a [f32],
    row_stride: usize,
    panel_stride: usize,
    halves: usize,
}

impl<'a> Panels<'a> {
    /// Panel `jp` from its first row on.
    fn panel(&self, jp: usize) -> &'a [f32] {
        &self.data[(jp / self.halves) * self.panel_stride + (jp % self.halves) * NR..]
    }
}

/// B packed once, for products that read it many times with few rows each (an actor's weights,
/// one pass per decision): panels of [`NR_WIDE`] columns over the whole depth, `k`-major,
/// zero-padded, so that a pass reads the weights in the order it uses them. The product
/// ([`gemm_packed`]) gives [`gemm`]'s bits.
#[derive(Debug, Clone, PartialEq)]
pub struct PackedB {
    data: Vec<f32>,
    k: usize,
    n: usize,
}

impl PackedB {
    /// `b` (`k x n`) in panels.
    pub fn new(b: Mat<'_>, k: usize, n: usize) -> Self {
        let mut data = vec![0.0; n.div_ceil(NR_WIDE) * NR_WIDE * k];
        if k > 0 {
            for (p, panel) in data.chunks_exact_mut(NR_WIDE * k).enumerate() {
                pack_b_panel::<NR_WIDE>(&b, 0, k, n, p * NR_WIDE, panel);
            }
        }
        Self { data, k, n }
    }

    /// Rows of B (the depth of the product).
    pub fn rows(&self) -> usize {
        self.k
    }

    /// Columns of B.
    pub fn cols(&self) -> usize {
        self.n
    }
}

/// [`gemm`] with B packed beforehand: `C = A B + (accumulate ? C : 0)`, A `m x k`.
pub fn gemm_packed(m: usize, a: Mat<'_>, b: &PackedB, c: &mut [f32], ldc: usize, accumulate: bool) {
    product(
        Kernel::detect(),
        m,
        b.n,
        b.k,
        a,
        BSource::Packed(b),
        c,
        ldc,
        accumulate,
    );
}

/// Where a product's B comes from.
#[derive(Clone, Copy)]
enum BSource<'a> {
    /// A view, packed per depth block when its panels are reused (see the module).
    View(Mat<'a>),
    /// Packed beforehand.
    Packed(&'a PackedB),
}

/// Whether the AVX2+FMA kernel runs on this CPU.
pub fn has_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}
