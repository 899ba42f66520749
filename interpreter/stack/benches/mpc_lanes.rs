//! The lab's grey-box MPC for two, four and eight vehicles: the solves one after the other against
//! one solve in as many lanes (the same bits; `tests/greybox_lanes.rs`). docs/performance.md quotes it:
//!
//!     cargo bench -p cpmx-stack --bench mpc_lanes

use std::hint::black_box;

use cpmx_follower::{
    LAB_MOVE_WEIGHTS, MpcConfig, Problem, ScalarPrediction, WarmStart, solve_lanes, solve_one,
};
use cpmx_stack::GreyBoxMpcModel;
use cpmx_vehicle::GreyBoxParams;
use criterion::{Criterion, criterion_group, criterion_main};

/// `L` grey-box vehicles' problems (speeds, headings and turns of their own).
fn problems<const L: usize>() -> [Problem<4, 2>; L] {
    std::array::from_fn(|i| {
        let (speed, yaw) = (0.5 + 0.05 * i as f64, 0.3 * i as f64);
        let x0 = [0.1 * i as f64, -0.2, yaw, speed];
        Problem {
            x0,
            reference_m: std::array::from_fn(|k| {
                let t = 0.05 * (k + 1) as f64;
                let heading = yaw + 0.8 * t;
                [
                    x0[0] + speed * t * heading.cos(),
                    x0[1] + speed * t * heading.sin(),
                ]
            }),
            previous_input: [0.2, 0.05],
        }
    })
}

/// `L` vehicles' MPCs one by one against `L` lanes.
fn bench_width<const L: usize>(c: &mut Criterion) {
    let config = MpcConfig::lab(LAB_MOVE_WEIGHTS);
    let vehicles: [GreyBoxMpcModel; L] =
        std::array::from_fn(|_| GreyBoxMpcModel::new(GreyBoxParams::LAB).expect("the lab's parameters"));
    let problems = problems::<L>();
    let mut group = c.benchmark_group(format!("grey-box MPC, {L} vehicles"));
    group.bench_function("one by one", |b| {
        let mut warm: [WarmStart<2>; L] = std::array::from_fn(|_| WarmStart::reset());
        b.iter(|| {
            for i in 0..L {
                let p = &problems[i];
                black_box(solve_one(
                    &ScalarPrediction(&vehicles[i]),
                    &config,
                    &p.x0,
                    &p.reference_m,
                    &p.previous_input,
                    &mut warm[i],
                ));
            }
        })
    });
    group.bench_function(format!("in {L} lanes"), |b| {
        let mut warm: [WarmStart<2>; L] = std::array::from_fn(|_| WarmStart::reset());
        b.iter(|| {
            black_box(solve_lanes(
                vehicles.each_ref(),
                &config,
                &problems,
                warm.each_mut(),
            ))
        })
    });
    group.finish();
}

fn bench(c: &mut Criterion) {
    bench_width::<1>(c);
    bench_width::<2>(c);
    bench_width::<4>(c);
    bench_width::<8>(c);
}

criterion_group!(benches, bench);
criterion_main!(benches);
