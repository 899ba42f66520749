//! The CBF filter for every vehicle of a step at once, with rows that keep the vehicles apart
//! (SigmaRL's later centralised QP, `cbf_qp.py` after tag 1.4.0): each vehicle is a row of
//! circles that cover its footprint; for each pair of vehicles closer than `range_m`, and each
//! pair of their circles, the truncated-Taylor CBF on h = ‖p_i − p_j‖² − (2r)² couples both
//! vehicles' inputs. The answer is the joint QP's over all of them: each vehicle is filtered
//! alone first (exactly as SigmaRL's 1.4.0 filter does), and only vehicles whose answers break
//! a row between them are solved together, in one QP with their boundary rows. Unlike
//! SigmaRL's grouped QP, no neighbour's input is assumed zero.

use std::sync::Arc;

use crate::cbf::{
    Arithmetic, CbfOutcome, CbfParameters, CbfRow, CbfState, Command, Fallback, Motion, active_rows, filter,
};
use crate::predictor::{MarginPredictor, predicted_row};
use crate::pseudo_distance::Boundary;
use crate::qp::{QpRow, solve_relaxing};

/// The rows between vehicles.
#[derive(Debug, Clone, PartialEq)]
pub struct AgentRows {
    /// The length of the footprint the circles cover [m] (the filter's `circles` of them along
    /// it, each of the radius that covers its share of the footprint).
    pub length_m: f64,
    /// The footprint's width [m].
    pub width_m: f64,
    /// Two vehicles whose centres are closer than this get rows [m].
    pub range_m: f64,
    /// The margin between two cars: `None`, circles (each of the filter's circles of one car
    /// against each of the other's, kept a diameter apart); or one row on the MTV-based margin
    /// a network predicts from their relative pose (SigmaRL's ECC 2025 margin).
    pub predictor: Option<Arc<MarginPredictor>>,
}

impl AgentRows {
    /// The radius of `circles` circles that cover the footprint (SigmaRL's
    /// `RectangleCircleApproximation`).
    pub fn circle_radius_m(&self, circles: usize) -> f64 {
        (self.length_m / (2.0 * circles as f64)).hypot(self.width_m / 2.0)
    }
}

/// One vehicle of a step: its state, its nominal command and its lane's boundaries.
#[derive(Debug, Clone, Copy)]
pub struct Vehicle<'a> {
    /// The state.
    pub state: CbfState,
    /// The nominal command `[speed m/s, steering rad]`.
    pub nominal: [f32; 2],
    /// The left boundary.
    pub left: &'a Boundary,
    /// The right boundary.
    pub right: &'a Boundary,
}

/// A row between two vehicles: `Σ coefficients · u + constant ≥ 0`.
#[derive(Debug, Clone, PartialEq)]
pub struct PairRow {
    /// The two vehicles (indices into the step's vehicles).
    pub vehicles: [usize; 2],
    /// The margin the row keeps.
    pub margin: PairMargin,
    /// Each vehicle's coefficients of acceleration and steering rate.
    pub coefficients: [[f64; 2]; 2],
    /// The constant.
    pub constant: f64,
}

/// The margin a row between two vehicles keeps positive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PairMargin {
    /// Between two circles (0 at the rear): h = ‖p_i − p_j‖² − (2r)².
    Circles {
        circles: [usize; 2],
        /// h [m²].
        barrier_m2: f64,
    },
    /// The predicted MTV-based margin of the two footprints less the network's error bound.
    Predicted {
        /// h [m].
        barrier_m: f64,
    },
}

/// What the filter did for a step's vehicles.
#[derive(Debug, Clone, PartialEq)]
pub struct StepOutcome {
    /// Each vehicle's outcome (its boundary rows in `rows`).
    pub vehicles: Vec<CbfOutcome>,
    /// The rows between vehicles.
    pub pair_rows: Vec<PairRow>,
    /// Indices into `pair_rows` of the rows the solution lies on, or (relaxed) violates.
    pub active_pairs: Vec<usize>,
}

/// Filters every vehicle's nominal command; with `p.agents`, vehicles in range of each other
/// are kept apart.
///
/// Each car is filtered alone first; cars whose answers break a row between them are then
/// solved together (with every row between the group's cars in range), and again until no
/// row between groups is broken. That is the joint QP's answer: each group's is optimal
/// without the rows between groups, and it satisfies them. Most steps need no joint QP.
pub fn filter_step(p: &CbfParameters, vehicles: &[Vehicle<'_>]) -> StepOutcome {
    let alone = |v: &Vehicle<'_>| filter(p, v.state, v.nominal, v.left, v.right);
    let mut outcomes: Vec<CbfOutcome> = vehicles.iter().map(alone).collect();
    let Some(agents) = &p.agents else {
        return StepOutcome {
            vehicles: outcomes,
            pair_rows: Vec::new(),
            active_pairs: Vec::new(),
        };
    };
    let pair_rows: Vec<PairRow> = near_pairs(vehicles, agents.range_m)
        .into_iter()
        .flat_map(|(i, j)| rows_between(p, agents, [i, j], [vehicles[i].state, vehicles[j].state]))
        .collect();
    let mut links: Vec<(usize, usize)> = Vec::new();
    let mut group_of: Vec<usize> = (0..vehicles.len()).collect();
    loop {
        let inputs: Vec<[f64; 2]> = outcomes.iter().map(applied_input).collect();
        let broken: Vec<(usize, usize)> = pair_rows
            .iter()
            .filter(|r| group_of[r.vehicles[0]] != group_of[r.vehicles[1]] && pair_value(r, &inputs) < 0.0)
            .map(|r| (r.vehicles[0], r.vehicles[1]))
            .collect();
        if broken.is_empty() {
            break;
        }
        // Only the groups a broken row joins change; the others keep their answers.
        let mut touched = vec![false; vehicles.len()];
        for &(i, j) in &broken {
            touched[i] = true;
            touched[j] = true;
        }
        links.extend(broken);
        for (index, group) in groups(vehicles.len(), &links).into_iter().enumerate() {
            for &v in &group {
                group_of[v] = index;
            }
            if group.len() < 2 || !group.iter().any(|&v| touched[v]) {
                continue;
            }
            let rows: Vec<PairRow> = pair_rows
                .iter()
                .filter(|r| group.contains(&r.vehicles[0]) && group.contains(&r.vehicles[1]))
                .cloned()
                .collect();
            // Each car's boundary rows as its lone filter computed them (the pseudo-distances
            // are most of a filter's cost).
            let lanes = group
                .iter()
                .map(|&v| std::mem::take(&mut outcomes[v].rows))
                .collect();
            for (vehicle, outcome) in group.iter().zip(filter_group(p, vehicles, &group, lanes, &rows)) {
                outcomes[*vehicle] = outcome;
            }
        }
    }
    let inputs: Vec<[f64; 2]> = outcomes.iter().map(applied_input).collect();
    let active_pairs = (0..pair_rows.len())
        .filter(|&k| pair_value(&pair_rows[k], &inputs) < 1e-7)
        .collect();
    StepOutcome {
        vehicles: outcomes,
        pair_rows,
        active_pairs,
    }
}

/// The input a car's outcome applies: the QP's, or the nominal one where it went through.
fn applied_input(outcome: &CbfOutcome) -> [f64; 2] {
    outcome.input.unwrap_or(outcome.nominal_input.map(f64::from))
}

/// A row between two cars at their `inputs`.
fn pair_value(row: &PairRow, inputs: &[[f64; 2]]) -> f64 {
    let term = |c: [f64; 2], u: [f64; 2]| c[0] * u[0] + c[1] * u[1];
    term(row.coefficients[0], inputs[row.vehicles[0]])
        + term(row.coefficients[1], inputs[row.vehicles[1]])
        + row.constant
}

/// The pairs `(i, j)`, `i < j`, whose centres are closer than `range_m`.
fn near_pairs(vehicles: &[Vehicle<'_>], range_m: f64) -> Vec<(usize, usize)> {
    let mut near = Vec::new();
    for (i, a) in vehicles.iter().enumerate() {
        for (j, b) in vehicles.iter().enumerate().skip(i + 1) {
            let distance = f64::from(a.state.x_m - b.state.x_m).hypot(f64::from(a.state.y_m - b.state.y_m));
            if distance < range_m {
                near.push((i, j));
            }
        }
    }
    near
}

/// The vehicles linked by `near`, directly or through others: each group in increasing order,
/// the groups by their first vehicle.
fn groups(count: usize, near: &[(usize, usize)]) -> Vec<Vec<usize>> {
    let mut group_of: Vec<usize> = (0..count).collect();
    fn root(group_of: &mut [usize], mut v: usize) -> usize {
        while group_of[v] != v {
            group_of[v] = group_of[group_of[v]];
            v = group_of[v];
        }
        v
    }
    for &(i, j) in near {
        let (a, b) = (root(&mut group_of, i), root(&mut group_of, j));
        group_of[a.max(b)] = a.min(b);
    }
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut index_of_root = vec![usize::MAX; count];
    for v in 0..count {
        let r = root(&mut group_of, v);
        if index_of_root[r] == usize::MAX {
            index_of_root[r] = groups.len();
            groups.push(Vec::new());
        }
        groups[index_of_root[r]].push(v);
    }
    groups
}

/// The rows between the circles of vehicles `pair` in `states`: for each circle pair,
/// `λh + ḣΔt + ½ḧΔt² ≥ 0` with h = ‖Δp‖² − (2r)², ḣ = 2Δp·Δv, ḧ = 2‖Δv‖² + 2Δp·Δp̈.
pub(crate) fn rows_between(
    p: &CbfParameters,
    agents: &AgentRows,
    pair: [usize; 2],
    states: [CbfState; 2],
) -> Vec<PairRow> {
    if let Some(predictor) = &agents.predictor {
        let row = predicted_row(p, predictor, [agents.length_m, agents.width_m], states);
        return vec![PairRow {
            vehicles: pair,
            margin: PairMargin::Predicted {
                barrier_m: row.barrier_m,
            },
            coefficients: row.coefficients,
            constant: row.constant,
        }];
    }
    let step = agents.length_m / p.circles as f64;
    let offsets: Vec<f64> = (0..p.circles)
        .map(|k| -agents.length_m / 2.0 + step / 2.0 + k as f64 * step)
        .collect();
    let safe_sq = (2.0 * agents.circle_radius_m(p.circles)).powi(2);
    let half_dt_sq = 0.5 * p.step_s * p.step_s;
    let circles = states.map(|s| {
        let motion = Motion::of(p, s);
        let (sin, cos) = f64::from(s.yaw_rad).sin_cos();
        let (sin32, cos32) = s.yaw_rad.sin_cos();
        offsets
            .iter()
            .map(|&offset| {
                let centre = match p.arithmetic {
                    Arithmetic::Numpy2 => [f64::from(s.x_m) + offset * cos, f64::from(s.y_m) + offset * sin],
                    // `get_circle_centers` in float32.
                    Arithmetic::Numpy1 => {
                        let offset32 = offset as f32;
                        [
                            f64::from(cos32 * offset32 + s.x_m),
                            f64::from(sin32 * offset32 + s.y_m),
                        ]
                    }
                };
                let (velocity, acceleration) = motion.point(offset);
                (centre, velocity, acceleration)
            })
            .collect::<Vec<_>>()
    });
    let mut rows = Vec::with_capacity(p.circles * p.circles);
    for (ci, (pi, vi, ai)) in circles[0].iter().enumerate() {
        for (cj, (pj, vj, aj)) in circles[1].iter().enumerate() {
            let dp = match p.arithmetic {
                Arithmetic::Numpy2 => [pi[0] - pj[0], pi[1] - pj[1]],
                Arithmetic::Numpy1 => [
                    f64::from(pi[0] as f32 - pj[0] as f32),
                    f64::from(pi[1] as f32 - pj[1] as f32),
                ],
            };
            let dv = [vi[0] - vj[0], vi[1] - vj[1]];
            let margin = dp[0] * dp[0] + dp[1] * dp[1] - safe_sq;
            let rate = 2.0 * (dp[0] * dv[0] + dp[1] * dv[1]);
            // ḧ's part without inputs, and its coefficients on each vehicle's [a, ω].
            let drift = 2.0 * (dv[0] * dv[0] + dv[1] * dv[1])
                + 2.0 * (dp[0] * (ai[0][0] - aj[0][0]) + dp[1] * (ai[1][0] - aj[1][0]));
            let on = |a: &[[f64; 3]; 2], sign: f64| -> [f64; 2] {
                std::array::from_fn(|u| sign * half_dt_sq * 2.0 * (dp[0] * a[0][u + 1] + dp[1] * a[1][u + 1]))
            };
            rows.push(PairRow {
                vehicles: pair,
                margin: PairMargin::Circles {
                    circles: [ci, cj],
                    barrier_m2: margin,
                },
                coefficients: [on(ai, 1.0), on(aj, -1.0)],
                constant: p.gain * margin + rate * p.step_s + half_dt_sq * drift,
            });
        }
    }
    rows
}

/// The QP of the vehicles `group` (increasing) with their boundary rows `lanes` (in the
/// group's order) and `pair_rows`; each vehicle's outcome.
fn filter_group(
    p: &CbfParameters,
    vehicles: &[Vehicle<'_>],
    group: &[usize],
    lanes: Vec<Vec<CbfRow>>,
    pair_rows: &[PairRow],
) -> Vec<CbfOutcome> {
    let commands: Vec<Command> = group
        .iter()
        .map(|&v| Command::of(p, vehicles[v].state, vehicles[v].nominal))
        .collect();
    let finite = group.iter().all(|&v| vehicles[v].state.is_finite())
        && lanes.iter().flatten().all(|r| r.is_finite())
        && pair_rows
            .iter()
            .all(|r| r.constant.is_finite() && r.coefficients.iter().flatten().all(|c| c.is_finite()));
    let all_fall_back = |why: Fallback, lanes: Vec<Vec<_>>| {
        commands
            .iter()
            .zip(lanes)
            .map(|(c, rows)| c.fallback(why, rows))
            .collect()
    };
    if !finite {
        return all_fall_back(Fallback::NotFinite, lanes);
    }
    let local = |vehicle: usize| {
        group
            .binary_search(&vehicle)
            .expect("a pair's vehicles are in its group")
    };
    let mut qp_rows: Vec<QpRow> = lanes
        .iter()
        .enumerate()
        .flat_map(|(v, rows)| rows.iter().map(move |r| QpRow::own(v, r)))
        .collect();
    qp_rows.extend(pair_rows.iter().map(|r| QpRow {
        first: (local(r.vehicles[0]), r.coefficients[0]),
        second: Some((local(r.vehicles[1]), r.coefficients[1])),
        constant: r.constant,
    }));
    let nominals: Vec<[f64; 2]> = commands.iter().map(Command::input64).collect();
    let (inputs, relaxed) = match solve_relaxing(p, &nominals, &qp_rows) {
        Ok(solution) => solution,
        Err(why) => return all_fall_back(why, lanes),
    };
    commands
        .iter()
        .zip(lanes)
        .zip(group)
        .zip(&inputs)
        .map(|(((command, rows), &v), &input)| {
            let active = active_rows(&rows, input);
            command.filtered(p, vehicles[v].state, input, rows, active, relaxed)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lane() -> (Boundary, Boundary) {
        let line = |y: f32| Boundary::new((0..121).map(|i| [-3.0 + 0.05 * i as f32, y]).collect()).unwrap();
        (line(0.15), line(-0.15))
    }

    fn parameters() -> CbfParameters {
        CbfParameters {
            agents: Some(AgentRows {
                length_m: 0.22,
                width_m: 0.107,
                range_m: 1.0,
                predictor: None,
            }),
            ..CbfParameters::sigmarl(0.1)
        }
    }

    fn at(x_m: f32, yaw_rad: f32, speed_mps: f32) -> CbfState {
        CbfState {
            x_m,
            y_m: 0.0,
            yaw_rad,
            speed_mps,
            steering_rad: 0.0,
        }
    }

    #[test]
    fn two_cars_head_on_are_slowed_and_a_lone_car_is_filtered_as_sigmarl_does() {
        let (left, right) = lane();
        let p = parameters();
        let vehicles = [
            Vehicle {
                state: at(-0.2, 0.0, 1.0),
                nominal: [1.0, 0.0],
                left: &left,
                right: &right,
            },
            Vehicle {
                state: at(0.2, std::f32::consts::PI, 1.0),
                nominal: [1.0, 0.0],
                left: &right,
                right: &left,
            },
            Vehicle {
                state: at(2.5, 0.0, 0.8),
                nominal: [0.8, 0.0],
                left: &left,
                right: &right,
            },
        ];
        let out = filter_step(&p, &vehicles);
        assert_eq!(out.pair_rows.len(), 9, "{:?}", out.pair_rows);
        assert!(!out.active_pairs.is_empty());
        for head_on in &out.vehicles[..2] {
            assert!(head_on.action[0] < 0.9, "{head_on:?}");
        }
        // The car 2.3 m away has no neighbour in range: SigmaRL's filter, alone.
        let alone = filter(&p, vehicles[2].state, vehicles[2].nominal, &left, &right);
        assert_eq!(out.vehicles[2], alone);
    }

    #[test]
    fn solving_the_cars_whose_rows_break_together_is_the_joint_qp() {
        let (left, right) = lane();
        let p = parameters();
        let car = |x_m: f32, yaw_rad: f32, speed_mps: f32| Vehicle {
            state: at(x_m, yaw_rad, speed_mps),
            nominal: [1.0, 0.0],
            left: &left,
            right: &right,
        };
        // Two cars head-on, a third 0.7 m past the second driving away: in range, never bound.
        let vehicles = [
            car(-0.2, 0.0, 1.0),
            car(0.2, std::f32::consts::PI, 1.0),
            car(0.9, 0.0, 0.8),
        ];
        let out = filter_step(&p, &vehicles);
        let rows: Vec<PairRow> = near_pairs(&vehicles, 1.0)
            .into_iter()
            .flat_map(|(i, j)| {
                rows_between(
                    &p,
                    p.agents.as_ref().unwrap(),
                    [i, j],
                    [vehicles[i].state, vehicles[j].state],
                )
            })
            .collect();
        assert_eq!(
            rows.len(),
            18,
            "two pairs in range (the first and the third car are 1.1 m apart)"
        );
        let lanes = vehicles
            .iter()
            .map(|v| crate::cbf::rows(&p, v.state, v.left, v.right))
            .collect();
        let joint = filter_group(&p, &vehicles, &[0, 1, 2], lanes, &rows);
        for (step, joint) in out.vehicles.iter().zip(&joint) {
            for (a, b) in step.input.unwrap().iter().zip(joint.input.unwrap()) {
                assert!((a - b).abs() < 1e-6, "{step:?} {joint:?}");
            }
        }
        // The third car was filtered alone, as SigmaRL's filter would.
        assert_eq!(
            out.vehicles[2],
            filter(&p, vehicles[2].state, vehicles[2].nominal, &left, &right)
        );
    }

    #[test]
    fn the_groups_follow_the_chains_of_near_pairs() {
        assert_eq!(
            groups(5, &[(0, 3), (3, 4)]),
            vec![vec![0, 3, 4], vec![1], vec![2]]
        );
        assert_eq!(groups(4, &[(2, 3), (0, 1), (1, 2)]), vec![vec![0, 1, 2, 3]]);
        assert_eq!(groups(0, &[]), Vec::<Vec<usize>>::new());
    }

    #[test]
    fn without_agent_rows_each_vehicle_is_filtered_alone() {
        let (left, right) = lane();
        let p = CbfParameters::sigmarl(0.1);
        let v = Vehicle {
            state: at(0.0, 0.0, 1.0),
            nominal: [1.0, 0.0],
            left: &left,
            right: &right,
        };
        let w = Vehicle {
            state: at(0.1, 0.0, 1.0),
            ..v
        };
        let out = filter_step(&p, &[v, w]);
        assert!(out.pair_rows.is_empty());
        assert_eq!(out.vehicles[1], filter(&p, w.state, w.nominal, &left, &right));
    }
}
