//! Several vehicles' 50 Hz steps at once, their MPCs solved side by side in SIMD lanes.
//!
//! A step of one vehicle is its estimate, its follower's decision, the delay, the plant and
//! the sensing (`stack.rs`); of these only the MPC's 20 gradient iterations cost much, and
//! they are the same straight-line code for every vehicle of a plant. So every vehicle's step
//! is begun, the MPC problems left pending are solved together
//! ([`cpmx_follower::solve_together`]: eight, four or two at a time, each lane with its
//! vehicle's own model, battery voltage and warm start), and every step is ended. The vehicles
//! share nothing during a step (each has its own state, follower and random stream), so the
//! order changes nothing and every vehicle gets the bits its own [`VehicleStack::step`] gives
//! (`tests/together.rs`).
//!
//! This module owns the order of the halves; the halves are `stack.rs`'s, the lanes
//! `cpmx-follower`'s.

use cpmx_follower::{Begun, LaneJob, Output, solve_together};

use crate::VehicleStack;
use crate::plants::Plant;
use crate::stack::Vehicle;

/// One 20 ms step of each vehicle from its own `now_ns` (the same as
/// [`VehicleStack::step`] on each in turn, with the MPCs solved together).
pub fn step_together<'a>(vehicles: impl IntoIterator<Item = (&'a mut VehicleStack, u64)>) {
    let mut kinematic = Vec::new();
    let mut grey_box = Vec::new();
    for (stack, now_ns) in vehicles {
        match stack {
            VehicleStack::Kinematic(v) => kinematic.push((&mut **v, now_ns)),
            VehicleStack::GreyBox(v) => grey_box.push((&mut **v, now_ns)),
        }
    }
    step_plant_together(&mut kinematic);
    step_plant_together(&mut grey_box);
}

/// [`step_together`] for the vehicles of one plant.
fn step_plant_together<P: Plant<NX, NU>, const NX: usize, const NU: usize>(
    vehicles: &mut [(&mut Vehicle<P, NX, NU>, u64)],
) {
    let begun: Vec<Begun<Output<NU>, NX, NU>> = vehicles
        .iter_mut()
        .map(|(vehicle, now_ns)| vehicle.begin_step(*now_ns))
        .collect();
    let results = {
        let mut jobs: Vec<LaneJob<'_, P::Model, NX, NU>> = vehicles
            .iter_mut()
            .zip(&begun)
            .filter_map(|((vehicle, _), begun)| match begun {
                Begun::Decided(_) => None,
                Begun::Gradient(pending) => {
                    let (model, config, warm) = vehicle.follower_mut().mpc_mut().gradient_parts();
                    Some(LaneJob {
                        model,
                        config,
                        warm,
                        problem: &pending.problem,
                    })
                }
            })
            .collect();
        solve_together(&mut jobs)
    };
    let mut results = results.into_iter();
    for ((vehicle, now_ns), begun) in vehicles.iter_mut().zip(begun) {
        let output = match begun {
            Begun::Decided(output) => output,
            Begun::Gradient(pending) => {
                let result = results.next().expect("one result per pending problem");
                vehicle.follower_mut().finish(&pending, result)
            }
        };
        vehicle.end_step(*now_ns, output);
    }
}
