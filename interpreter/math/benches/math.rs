//! cpmx-math against the platform's libm (Rust's std), per call and over slices of 1,024
//! arguments in the ranges the twin uses (docs/performance.md quotes the figures):
//!
//!     cargo bench -p cpmx-math --bench math

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};

/// Headings in a run's range (unwrapped yaw plus steering terms) and motor throttles.
fn arguments() -> (Vec<f64>, Vec<f64>) {
    let headings = (0..1024)
        .map(|i| -40.0 + 80.0 * (i as f64 * 0.618_034).fract())
        .collect();
    let throttles = (0..1024).map(|i| (i as f64 * 0.381_966).fract()).collect();
    (headings, throttles)
}

fn bench(c: &mut Criterion) {
    let (headings, throttles) = arguments();
    let exponents = vec![1.321199; 1024];
    let (mut sin, mut cos, mut out) = (vec![0.0; 1024], vec![0.0; 1024], vec![0.0; 1024]);
    let mut group = c.benchmark_group("sin_cos x1024");
    group.bench_function("libm, scalar", |b| {
        b.iter(|| {
            for (i, x) in black_box(&headings).iter().enumerate() {
                (sin[i], cos[i]) = x.sin_cos();
            }
        })
    });
    group.bench_function("cpmx-math, scalar", |b| {
        b.iter(|| {
            for (i, x) in black_box(&headings).iter().enumerate() {
                (sin[i], cos[i]) = cpmx_math::sin_cos(*x);
            }
        })
    });
    group.bench_function("cpmx-math, lanes", |b| {
        b.iter(|| cpmx_math::sin_cos_slice(black_box(&headings), &mut sin, &mut cos))
    });
    group.finish();
    let mut group = c.benchmark_group("pow x1024");
    group.bench_function("libm, scalar", |b| {
        b.iter(|| {
            for (i, x) in black_box(&throttles).iter().enumerate() {
                out[i] = x.powf(1.321199);
            }
        })
    });
    group.bench_function("cpmx-math, scalar", |b| {
        b.iter(|| {
            for (i, x) in black_box(&throttles).iter().enumerate() {
                out[i] = cpmx_math::pow(*x, 1.321199);
            }
        })
    });
    group.bench_function("cpmx-math, lanes", |b| {
        b.iter(|| cpmx_math::pow_slice(black_box(&throttles), &exponents, &mut out))
    });
    group.finish();
    let mut group = c.benchmark_group("exp x1024");
    group.bench_function("libm, scalar", |b| {
        b.iter(|| {
            for (i, x) in black_box(&headings).iter().enumerate() {
                out[i] = x.exp();
            }
        })
    });
    group.bench_function("cpmx-math, lanes", |b| {
        b.iter(|| cpmx_math::exp_slice(black_box(&headings), &mut out))
    });
    group.finish();
    // Steering angles of the bicycle model (tan δ, then atan of its scaled tangent).
    let steering: Vec<f64> = throttles.iter().map(|t| 0.7 * (2.0 * t - 1.0)).collect();
    let mut group = c.benchmark_group("tan x1024");
    group.bench_function("libm, scalar", |b| {
        b.iter(|| {
            for (i, x) in black_box(&steering).iter().enumerate() {
                out[i] = x.tan();
            }
        })
    });
    group.bench_function("cpmx-math, scalar", |b| {
        b.iter(|| {
            for (i, x) in black_box(&steering).iter().enumerate() {
                out[i] = cpmx_math::tan(*x);
            }
        })
    });
    group.bench_function("cpmx-math, lanes", |b| {
        b.iter(|| cpmx_math::tan_slice(black_box(&steering), &mut out))
    });
    group.finish();
    let mut group = c.benchmark_group("atan x1024");
    group.bench_function("libm, scalar", |b| {
        b.iter(|| {
            for (i, x) in black_box(&steering).iter().enumerate() {
                out[i] = x.atan();
            }
        })
    });
    group.bench_function("cpmx-math, scalar", |b| {
        b.iter(|| {
            for (i, x) in black_box(&steering).iter().enumerate() {
                out[i] = cpmx_math::atan(*x);
            }
        })
    });
    group.finish();
    // Velocities of a reference trajectory: (vx, vy) on a circle of speeds up to 1.5 m/s.
    let vx: Vec<f64> = headings
        .iter()
        .zip(&throttles)
        .map(|(h, t)| 1.5 * t * h.cos())
        .collect();
    let vy: Vec<f64> = headings
        .iter()
        .zip(&throttles)
        .map(|(h, t)| 1.5 * t * h.sin())
        .collect();
    let mut group = c.benchmark_group("atan2 x1024");
    group.bench_function("libm, scalar", |b| {
        b.iter(|| {
            for (i, (y, x)) in black_box(&vy).iter().zip(&vx).enumerate() {
                out[i] = y.atan2(*x);
            }
        })
    });
    group.bench_function("cpmx-math, scalar", |b| {
        b.iter(|| {
            for (i, (y, x)) in black_box(&vy).iter().zip(&vx).enumerate() {
                out[i] = cpmx_math::atan2(*y, *x);
            }
        })
    });
    group.bench_function("cpmx-math, lanes", |b| {
        b.iter(|| cpmx_math::atan2_slice(black_box(&vy), &vx, &mut out))
    });
    group.finish();
    let mut group = c.benchmark_group("hypot x1024");
    group.bench_function("libm, scalar", |b| {
        b.iter(|| {
            for (i, (x, y)) in black_box(&vx).iter().zip(&vy).enumerate() {
                out[i] = x.hypot(*y);
            }
        })
    });
    group.bench_function("cpmx-math, scalar", |b| {
        b.iter(|| {
            for (i, (x, y)) in black_box(&vx).iter().zip(&vy).enumerate() {
                out[i] = cpmx_math::hypot(*x, *y);
            }
        })
    });
    group.bench_function("cpmx-math, lanes", |b| {
        b.iter(|| cpmx_math::hypot_slice(black_box(&vx), &vy, &mut out))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
