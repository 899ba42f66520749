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
    let start: [[f32; NR]; MR] = std::array::from_fn(|r| std::array::from_fn(|c| (r * NR + c) as f32 * 0.01));
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
