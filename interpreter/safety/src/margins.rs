//! The CBF constraints' values under a joint action, without solving anything: SigmaRL's
//! CBF-informed reward of the ITSC 2026 paper (`cbf_qp.py`
//! `compute_nominal_cbf_constraint_margins` and `compute_cbf_violation_rewards_from_margins`
//! at tag 1.6.0). Each vehicle's sampled command becomes the acceleration and steering rate
//! that reach it over one step; the truncated-Taylor rows of the filter (its lanes' boundaries,
//! and every pair of vehicles' circles) are evaluated at those inputs. A row's value `g` is
//! its predicted margin: negative where the joint action breaks the constraint.

use crate::agents::{AgentRows, Vehicle, rows_between};
use crate::cbf::{CbfParameters, Command, Side, rows};

/// What the margins are computed with.
#[derive(Debug, Clone, PartialEq)]
pub struct MarginParameters {
    /// The rows' parameters: circles, the radius kept from a boundary (SigmaRL 1.6.0: the
    /// radius that covers the vehicle), λ (0.5), the Taylor horizon as `step_s` (two steps);
    /// `agents` for the rows between vehicles (every pair, whatever its distance, when its
    /// range is infinite). Its limits and ranges convert commands into inputs.
    pub rows: CbfParameters,
    /// The step a command is reached over [s] (the environment's `dt`).
    pub command_step_s: f64,
}

/// One vehicle's worst row values under the joint action.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleMargins {
    /// The smallest value of its circles' rows against the left boundary.
    pub left: f64,
    /// ... against the right boundary.
    pub right: f64,
    /// The smallest value of the rows between its circles and another vehicle's, at most 0
    /// (0 without another vehicle).
    pub agents: f64,
}

impl VehicleMargins {
    /// SigmaRL's reward of the margins: the mean of `clamp(value / threshold, −1, 0)` over the
    /// three (0 where every row holds, −1 once a margin is `threshold` short).
    pub fn reward(&self, threshold: f64) -> f64 {
        let r = |g: f64| (g / threshold).clamp(-1.0, 0.0);
        (r(self.left) + r(self.right) + r(self.agents)) / 3.0
    }
}

/// Every vehicle's margins under the joint action of the vehicles' `nominal` commands.
pub fn joint_margins(p: &MarginParameters, vehicles: &[Vehicle<'_>]) -> Vec<VehicleMargins> {
    let inputs: Vec<[f64; 2]> = vehicles
        .iter()
        .map(|v| Command::over(&p.rows, v.state, v.nominal, p.command_step_s).input64())
        .collect();
    let mut margins: Vec<VehicleMargins> = vehicles
        .iter()
        .zip(&inputs)
        .map(|(v, u)| {
            let mut m = VehicleMargins {
                left: f64::INFINITY,
                right: f64::INFINITY,
                agents: 0.0,
            };
            for row in rows(&p.rows, v.state, v.left, v.right) {
                let g = row.coefficients[0] * u[0] + row.coefficients[1] * u[1] + row.constant;
                let side = match row.side {
                    Side::Left => &mut m.left,
                    Side::Right => &mut m.right,
                };
                *side = side.min(g);
            }
            m
        })
        .collect();
    if let Some(agents) = &p.rows.agents {
        for i in 0..vehicles.len() {
            for j in i + 1..vehicles.len() {
                if !within(agents, &vehicles[i], &vehicles[j]) {
                    continue;
                }
                for row in rows_between(&p.rows, agents, [i, j], [vehicles[i].state, vehicles[j].state]) {
                    let term = |c: [f64; 2], u: [f64; 2]| c[0] * u[0] + c[1] * u[1];
                    let g = term(row.coefficients[0], inputs[i])
                        + term(row.coefficients[1], inputs[j])
                        + row.constant;
                    margins[i].agents = margins[i].agents.min(g);
                    margins[j].agents = margins[j].agents.min(g);
                }
            }
        }
    }
    margins
}

/// Whether two vehicles' centres are within the rows' range.
fn within(agents: &AgentRows, a: &Vehicle<'_>, b: &Vehicle<'_>) -> bool {
    let distance = f64::from(a.state.x_m - b.state.x_m).hypot(f64::from(a.state.y_m - b.state.y_m));
    distance < agents.range_m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Boundary, CbfState};

    fn lane() -> (Boundary, Boundary) {
        let line = |y: f32| Boundary::new((0..81).map(|i| [-2.0 + 0.05 * i as f32, y]).collect()).unwrap();
        (line(0.15), line(-0.15))
    }

    /// SigmaRL 1.6.0's reward setting for the 0.16 m car at dt 0.1: λ 0.5, Taylor horizon
    /// 0.2 s, three covering circles, every pair.
    fn parameters() -> MarginParameters {
        let agents = AgentRows {
            length_m: 0.16,
            width_m: 0.08,
            range_m: f64::INFINITY,
            predictor: None,
        };
        MarginParameters {
            rows: CbfParameters {
                circle_radius_m: agents.circle_radius_m(3),
                gain: 0.5,
                step_s: 0.2,
                acceleration_limit_mps2: 5.0,
                steering_rate_limit_radps: std::f64::consts::FRAC_PI_2,
                agents: Some(agents),
                ..CbfParameters::sigmarl(0.2)
            },
            command_step_s: 0.1,
        }
    }

    fn at(x_m: f32, y_m: f32, yaw_rad: f32) -> CbfState {
        CbfState {
            x_m,
            y_m,
            yaw_rad,
            speed_mps: 0.5,
            steering_rad: 0.0,
        }
    }

    #[test]
    fn a_centred_car_costs_nothing_and_one_steering_out_is_penalised() {
        let (left, right) = lane();
        let p = parameters();
        let car = |state, nominal| Vehicle {
            state,
            nominal,
            left: &left,
            right: &right,
        };
        let calm = joint_margins(&p, &[car(at(0.0, 0.0, 0.0), [0.5, 0.0])]);
        assert!(
            calm[0].left > 0.0 && calm[0].right > 0.0 && calm[0].agents == 0.0,
            "{calm:?}"
        );
        assert_eq!(calm[0].reward(0.1), 0.0);
        // Near the left boundary, heading and steering into it: the left rows break.
        let out = joint_margins(&p, &[car(at(0.0, 0.08, 0.4), [1.0, 0.5])]);
        assert!(out[0].left < 0.0 && out[0].right > 0.0, "{out:?}");
        let r = out[0].reward(0.1);
        assert!((-1.0 / 3.0..0.0).contains(&r), "{r}");
    }

    #[test]
    fn two_cars_driving_at_each_other_share_the_pair_penalty_and_it_depends_on_both_actions() {
        let (left, right) = lane();
        let p = parameters();
        let head_on = |nominal_b: [f32; 2]| {
            let a = Vehicle {
                state: at(0.0, 0.0, 0.0),
                nominal: [1.0, 0.0],
                left: &left,
                right: &right,
            };
            let b = Vehicle {
                state: at(0.3, 0.0, std::f32::consts::PI),
                nominal: nominal_b,
                ..a
            };
            [a, b]
        };
        let both_fast = joint_margins(&p, &head_on([1.0, 0.0]));
        assert!(both_fast[0].agents < 0.0, "{both_fast:?}");
        assert_eq!(both_fast[0].agents, both_fast[1].agents);
        let one_brakes = joint_margins(&p, &head_on([-0.5, 0.0]));
        assert!(
            one_brakes[0].agents > both_fast[0].agents,
            "{one_brakes:?} vs {both_fast:?}"
        );
        // Without rows between cars, the pair costs nothing.
        let alone = MarginParameters {
            rows: CbfParameters {
                agents: None,
                ..p.rows.clone()
            },
            ..p
        };
        assert_eq!(joint_margins(&alone, &head_on([1.0, 0.0]))[0].agents, 0.0);
    }
}
