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

/// Pack rows `pc..pc + kc` of B into micro-panels of `W` columns, `k`-major, zero-padded;
/// panels are split between rayon's threads when there are several (a copy: no bit changes).
fn pack_b<const W: usize>(b: &Mat<'_>, pc: usize, kc: usize, n: usize, out: &mut [f32]) {
    let panel = |(p, panel): (usize, &mut [f32])| pack_b_panel::<W>(b, pc, kc, n, p * W, panel);
    if rayon::current_num_threads() > 1 && n >= 4 * W {
        out.par_chunks_exact_mut(W * kc).enumerate().for_each(panel);
    } else {
        out.chunks_exact_mut(W * kc).enumerate().for_each(panel);
    }
}

/// One micro-panel of [`pack_b`]: columns `j0..j0 + W` of B's rows `pc..pc + kc`.
fn pack_b_panel<const W: usize>(b: &Mat<'_>, pc: usize, kc: usize, n: usize, j0: usize, panel: &mut [f32]) {
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
fn pack_a(a: &Mat<'_>, i0: usize, rows: usize, pc: usize, kc: usize, out: &mut [f32]) {
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

/// All tiles of one row block: `c_block` starts at the block's first row. Full tiles are
/// updated in place; edge tiles go through a zero-padded copy.
#[allow(clippy::too_many_arguments)]
fn block_product(
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
const FEW_ROWS: usize = 3;
/// Columns of [`few_rows_product`]'s tile (four 256-bit vectors).
#[cfg(target_arch = "x86_64")]
const FEW_ROWS_COLUMNS: usize = 32;

/// At most [`FEW_ROWS`] rows with the AVX2 kernel, A read in place (the agents of a run through
/// an actor's layer): tiles of `rows` x 32, `a` starting at the block's first row and depth,
/// B's 32-column panels in place or packed beforehand ([`PackedB`]). The sums are the other kernels' (one fused multiply-add per
/// term in increasing `k`), so are the bits.
#[cfg(target_arch = "x86_64")]
#[allow(clippy::too_many_arguments)]
fn few_rows_product(
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

/// # Safety
/// The CPU must support AVX2 and FMA; `a` must be valid at `r * rs + kk * cs` for `r < R`,
/// `kk < kc`, `b` at `kk * ldb + j` for `j < 32`, and `c` at `r * ldc + j`, `j < 32`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[allow(clippy::too_many_arguments)]
unsafe fn few_rows_kernel_avx2<const R: usize>(
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
fn micro_kernel(
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

/// All tiles of one row block with the AVX-512 kernel, reading A in place: `a` starts at the
/// block's first row and depth (element `(i, kk)` at `i * rs + kk * cs`), `packed_b` holds the
/// depth block's panels of [`NR_WIDE`] columns, `c_block` starts at the block's first row.
/// Full tiles are updated in place; tiles over the last columns go through a zero-padded copy.
#[allow(clippy::too_many_arguments)]
fn block_product_wide(
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

/// The AVX-512 tile of `rows` (1 to [`MR_WIDE`]) rows and `vectors` (1 or 2) times 16
/// columns: `C_tile (+)= A_tile B_panel` over `kc` terms, A element `(r, kk)` at
/// `a[r * rs + kk * cs]`, B row `kk` at `b[kk * ldb..]`, C element `(r, j)` at
/// `c[r * ldc + j]`.
#[allow(clippy::too_many_arguments)]
fn wide_kernel(
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
unsafe fn micro_kernel_avx512<const R: usize, const V: usize>(
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
unsafe fn micro_kernel_avx2<const R: usize>(
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

#[cfg(test)]
mod tests {
    use super::*;

    fn naive(m: usize, n: usize, k: usize, a: &Mat<'_>, b: &Mat<'_>) -> Vec<f64> {
        let mut c = vec![0.0; m * n];
        for i in 0..m {
            for j in 0..n {
                c[i * n + j] = (0..k)
                    .map(|kk| f64::from(a.at(i, kk)) * f64::from(b.at(kk, j)))
                    .sum();
            }
        }
        c
    }

    fn data(len: usize, seed: f32) -> Vec<f32> {
        (0..len).map(|i| ((i as f32 + seed) * 0.7312).sin()).collect()
    }

    #[test]
    fn every_layout_and_edge_size_matches_a_naive_product() {
        for &(m, n, k) in &[(1, 1, 1), (7, 17, 3), (13, 33, 300), (130, 20, 257), (6, 16, 256)] {
            let a_rm = data(m * k, 1.0);
            let b_rm = data(k * n, 2.0);
            let a_t: Vec<f32> = (0..k * m).map(|x| a_rm[(x % m) * k + x / m]).collect();
            let b_t: Vec<f32> = (0..n * k).map(|x| b_rm[(x % k) * n + x / k]).collect();
            let want = naive(m, n, k, &Mat::rows(&a_rm, k), &Mat::rows(&b_rm, n));
            for (a, b) in [
                (Mat::rows(&a_rm, k), Mat::rows(&b_rm, n)),
                (Mat::transposed(&a_t, m), Mat::transposed(&b_t, k)),
            ] {
                let ldc = n + 3;
                let mut c = vec![1.0f32; m * ldc];
                gemm(m, n, k, a, b, &mut c, ldc, true);
                for i in 0..m {
                    for j in 0..n {
                        let got = f64::from(c[i * ldc + j]);
                        assert!(
                            (got - 1.0 - want[i * n + j]).abs() < 1e-4,
                            "{m}x{n}x{k} ({i},{j})"
                        );
                    }
                    assert_eq!(
                        c[i * ldc + n..i * ldc + ldc.min(n + 3)],
                        [1.0, 1.0, 1.0][..ldc - n]
                    );
                }
            }
        }
    }

    #[test]
    fn the_simd_kernel_gives_the_portable_kernels_bits() {
        let kc = 77;
        let a = data(kc * MR, 3.0);
        let b = data(kc * NR, 4.0);
        let start: [[f32; NR]; MR] =
            std::array::from_fn(|r| std::array::from_fn(|c| (r * NR + c) as f32 * 0.01));
        let bits = |t: &[[f32; NR]; MR]| t.iter().flatten().map(|v| v.to_bits()).collect::<Vec<_>>();
        let mut portable = start;
        micro_kernel_portable(MR, kc, &a, &b, NR, portable.as_flattened_mut(), NR, true);
        let mut chosen = start;
        micro_kernel(MR, kc, &a, &b, NR, chosen.as_flattened_mut(), NR, has_fma(), true);
        assert_eq!(bits(&portable), bits(&chosen));
        // Without loading C, both start from zero: the same as a zeroed C.
        let mut zeroed = [[0.0f32; NR]; MR];
        micro_kernel_portable(MR, kc, &a, &b, NR, zeroed.as_flattened_mut(), NR, true);
        for kernel in [false, true] {
            let mut fresh = start;
            if kernel {
                micro_kernel(MR, kc, &a, &b, NR, fresh.as_flattened_mut(), NR, has_fma(), false);
            } else {
                micro_kernel_portable(MR, kc, &a, &b, NR, fresh.as_flattened_mut(), NR, false);
            }
            assert_eq!(bits(&fresh), bits(&zeroed));
        }
    }

    #[test]
    fn every_kernel_gives_the_same_bits() {
        let kernels = Kernel::available();
        for &(m, n, k) in &[
            (1, 1, 1),
            (13, 17, 3),
            (37, 40, 300),
            (130, 20, 257),
            (24, 48, 600),
            (25, 64, 33),
            (12, 16, 9),
            (29, 100, 260),
            (3, 64, 300),
            (2, 96, 7),
            (1, 32, 260),
            (6, 32, 256),
            (1, 16, 9),
            (12, 64, 40),
        ] {
            let a_rm = data(m * k, 7.0);
            let b_rm = data(k * n, 8.0);
            let a_t: Vec<f32> = (0..k * m).map(|x| a_rm[(x % m) * k + x / m]).collect();
            let b_t: Vec<f32> = (0..n * k).map(|x| b_rm[(x % k) * n + x / k]).collect();
            for (a, b, accumulate) in [
                (Mat::rows(&a_rm, k), Mat::rows(&b_rm, n), true),
                (Mat::transposed(&a_t, m), Mat::rows(&b_rm, n), false),
                (Mat::rows(&a_rm, k), Mat::transposed(&b_t, k), true),
            ] {
                let run = |kernel: Kernel| {
                    let mut c: Vec<f32> = (0..m * (n + 2)).map(|i| i as f32 * 1e-3).collect();
                    gemm_with(kernel, m, n, k, a, b, &mut c, n + 2, accumulate);
                    c.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
                };
                let want = run(Kernel::Portable);
                for &kernel in &kernels {
                    assert_eq!(run(kernel), want, "{kernel:?} {m}x{n}x{k}");
                }
            }
        }
    }

    #[test]
    fn a_few_rows_read_in_place_give_the_bits_of_the_packed_product() {
        // Three rows (B read in place) against the same rows inside a product of 40 (packed).
        let (n, k) = (64, 300);
        let a = data(40 * k, 3.0);
        let b = data(k * n, 4.0);
        for kernel in Kernel::available() {
            let mut many = vec![0.5f32; 40 * n];
            gemm_with(
                kernel,
                40,
                n,
                k,
                Mat::rows(&a, k),
                Mat::rows(&b, n),
                &mut many,
                n,
                true,
            );
            let mut few = vec![0.5f32; 3 * n];
            gemm_with(
                kernel,
                3,
                n,
                k,
                Mat::rows(&a, k),
                Mat::rows(&b, n),
                &mut few,
                n,
                true,
            );
            let bits = |c: &[f32]| c.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&few), bits(&many[..3 * n]), "{kernel:?}");
        }
    }

    #[test]
    fn b_packed_beforehand_gives_the_bits_of_b_viewed() {
        for &(m, n, k) in &[
            (1, 32, 9),
            (3, 256, 256),
            (3, 4, 256),
            (5, 48, 300),
            (13, 64, 33),
            (40, 100, 260),
        ] {
            let a = data(m * k, 9.0);
            let b = data(k * n, 10.0);
            let packed = PackedB::new(Mat::rows(&b, n), k, n);
            for kernel in Kernel::available() {
                let run = |packed_b: bool| {
                    let mut c: Vec<f32> = (0..m * (n + 1)).map(|i| i as f32 * 1e-3).collect();
                    if packed_b {
                        product(
                            kernel,
                            m,
                            n,
                            k,
                            Mat::rows(&a, k),
                            BSource::Packed(&packed),
                            &mut c,
                            n + 1,
                            true,
                        );
                    } else {
                        gemm_with(
                            kernel,
                            m,
                            n,
                            k,
                            Mat::rows(&a, k),
                            Mat::rows(&b, n),
                            &mut c,
                            n + 1,
                            true,
                        );
                    }
                    c.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
                };
                assert_eq!(run(true), run(false), "{kernel:?} {m}x{n}x{k}");
            }
        }
    }

    #[test]
    fn thread_count_does_not_change_bits() {
        let (m, n, k) = (500, 40, 300);
        let a = data(m * k, 5.0);
        let b = data(k * n, 6.0);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut c = vec![0.0f32; m * n];
            pool.install(|| gemm(m, n, k, Mat::rows(&a, k), Mat::rows(&b, n), &mut c, n, false));
            c.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        };
        assert_eq!(run(1), run(3));
    }
}
