//! The CBF filter's cost per vehicle and step on the CPM map (`cargo bench -p cpmx-safety
//! --bench cbf`, needs SigmaRL's reference data): one car against reference path 0's road
//! boundaries (SigmaRL 1.4.0's filter: three circles, 18 pseudo-distances per boundary), and
//! three cars in one QP with the rows between them (`stdlib:sigmarl-cbf`). The states walk
//! along the path, a little off its centre line and heading out, with a nominal action that
//! turns further out, so most steps are changed by the QP, as in the paper's runs.

use std::hint::black_box;

use cpmx_safety::{AgentRows, Boundary, CbfParameters, CbfState, Vehicle, filter, filter_step};
use cpmx_world::Map;
use criterion::{Criterion, criterion_group, criterion_main};

/// Path 0's shared boundaries and centre-line poses every ~0.3 m: `(x, y, yaw)`.
fn lane() -> (Boundary, Boundary, Vec<[f64; 3]>) {
    let map = Map::load(cpmx_testdata::reference_file("maps/cpm.xml")).expect("the CPM map");
    let path = map.reference_path(0).expect("path 0");
    let boundary = |points: &[[f64; 2]]| {
        Boundary::new(points.iter().map(|p| [p[0] as f32, p[1] as f32]).collect()).expect("a boundary")
    };
    let poses = path
        .center_line
        .points
        .iter()
        .zip(&path.center_line_yaw_rad)
        .step_by(3)
        .map(|(p, &yaw)| [p[0], p[1], yaw])
        .collect();
    (
        boundary(&path.left_boundary_shared.points),
        boundary(&path.right_boundary_shared.points),
        poses,
    )
}

fn state(pose: [f64; 3], along_m: f64) -> CbfState {
    let (sin, cos) = pose[2].sin_cos();
    CbfState {
        x_m: (pose[0] + along_m * cos - 0.03 * sin) as f32,
        y_m: (pose[1] + along_m * sin + 0.03 * cos) as f32,
        yaw_rad: (pose[2] + 0.1) as f32,
        speed_mps: 0.8,
        steering_rad: 0.05,
    }
}

fn bench(c: &mut Criterion) {
    let (left, right, poses) = lane();
    let single = CbfParameters::sigmarl(0.1);
    let mut k = 0;
    c.bench_function("cbf/one car, CPM path 0", |b| {
        b.iter(|| {
            k = (k + 1) % poses.len();
            black_box(filter(&single, state(poses[k], 0.0), [1.0, 0.3], &left, &right))
        })
    });
    let mut k = 0;
    c.bench_function("cbf/one car's rows, CPM path 0", |b| {
        b.iter(|| {
            k = (k + 1) % poses.len();
            black_box(cpmx_safety::cbf::rows(
                &single,
                state(poses[k], 0.0),
                &left,
                &right,
            ))
        })
    });
    let joint = CbfParameters {
        agents: Some(AgentRows {
            length_m: 0.22,
            width_m: 0.107,
            range_m: 1.0,
            predictor: None,
        }),
        slack_weight: Some(1e9),
        ..single
    };
    let mut k = 0;
    c.bench_function("cbf/three cars 0.3 m apart, their rows binding (per step)", |b| {
        b.iter(|| {
            k = (k + 1) % poses.len();
            let vehicles: Vec<Vehicle<'_>> = [0.0, 0.3, 0.6]
                .iter()
                .map(|&along| Vehicle {
                    state: state(poses[k], along),
                    nominal: [1.0, 0.3],
                    left: &left,
                    right: &right,
                })
                .collect();
            black_box(filter_step(&joint, &vehicles))
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
