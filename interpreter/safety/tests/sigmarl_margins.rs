//! The CBF-informed reward's margins against SigmaRL's own: each case's states and sampled
//! actions went through SigmaRL's `CBFQP.update_qp` with `is_solve_qp = False`
//! (`compute_nominal_cbf_constraint_margins`, `compute_cbf_violation_rewards_from_margins`;
//! bassamlab/SigmaRL tag 1.6.0 unchanged, under the NumPy 1.26.4 it pins; the generator is
//! `research/cbf_margins_cases.py`, `research/cbf-margins-cases.md` says how). SigmaRL 1.6.0's
//! car is the µCar (0.22 m × 0.107 m, wheelbase 0.15 m), three circles of the covering
//! radius, λ 0.5, a Taylor horizon of 0.2 s, dt 0.1 s, threshold 0.1.

mod support;

use cpmx_safety::margins::{MarginParameters, joint_margins};
use cpmx_safety::{AgentRows, Arithmetic, CbfParameters, CbfState, Vehicle};
use support::Lane;

struct Agent {
    /// x, y, heading, signed speed, steering.
    state: [f64; 5],
    /// Target speed and steering.
    action: [f64; 2],
    /// The worst left and right lane rows.
    lanes: [f64; 2],
    /// The agent's three reward terms r_L, r_R, r_P.
    terms: [f64; 3],
}

struct Case {
    name: &'static str,
    lane: Lane,
    agents: &'static [Agent],
    /// The worst row between agents i < j.
    pairs: &'static [((usize, usize), f64)],
}

const PI: f64 = std::f64::consts::PI;

const CASES: &[Case] = &[
    Case {
        name: "C1 centred",
        lane: Lane::Straight,
        agents: &[Agent {
            state: [0.0, 0.0, 0.0, 0.5, 0.0],
            action: [0.6, 0.0],
            lanes: [0.04258268944138889, 0.04258268944138889],
            terms: [0.0, 0.0, 0.0],
        }],
        pairs: &[],
    },
    Case {
        name: "C2 steering left near the left boundary",
        lane: Lane::Straight,
        agents: &[Agent {
            state: [0.0, 0.02, 0.2, 0.5, 0.05],
            action: [0.6, 0.15],
            lanes: [-0.015586177612537843, 0.07090925964778216],
            terms: [-0.1558617761253784, 0.0, 0.0],
        }],
        pairs: &[],
    },
    Case {
        name: "C3 arc, saturated at the outer boundary",
        lane: Lane::Arc,
        agents: &[Agent {
            state: [
                1.053358626805252,
                0.1184719516803623,
                1.1827963267948967,
                1.0,
                -0.2,
            ],
            action: [1.0, -0.5],
            lanes: [0.20504255988525957, -0.19202136176147677],
            terms: [0.0, -1.0, 0.0],
        }],
        pairs: &[],
    },
    Case {
        name: "C4 clamped action",
        lane: Lane::Straight,
        agents: &[Agent {
            state: [0.5, 0.0, 0.2, 0.2, 0.1],
            action: [1.5, 0.9],
            lanes: [-0.01261563152544213, 0.06378305892673257],
            terms: [-0.12615631525442128, 0.0, 0.0],
        }],
        pairs: &[],
    },
    Case {
        name: "C5 reversing",
        lane: Lane::Straight,
        agents: &[Agent {
            state: [0.0, -0.05, 0.3, -0.4, 0.1],
            action: [-0.8, -0.2],
            lanes: [0.08191973135132424, -0.020822687301038346],
            terms: [0.0, -0.20822687301038345, 0.0],
        }],
        pairs: &[],
    },
    Case {
        name: "C6 head-on",
        lane: Lane::Straight,
        agents: &[
            Agent {
                state: [-0.16, 0.0, 0.0, 0.8, 0.0],
                action: [1.0, 0.0],
                lanes: [0.04258268944138889, 0.04258268944138889],
                terms: [0.0, 0.0, -1.0],
            },
            Agent {
                state: [0.16, 0.01, PI, 0.8, 0.0],
                action: [1.0, 0.05],
                lanes: [0.03766679982628975, 0.039668717828702925],
                terms: [0.0, 0.0, -1.0],
            },
        ],
        pairs: &[((0, 1), -0.17040959906814573)],
    },
    Case {
        name: "C7 arc, two cars apart",
        lane: Lane::Arc,
        agents: &[
            Agent {
                state: [
                    0.9517215483530664,
                    -0.30696269219636757,
                    1.2587963267948965,
                    0.6,
                    0.1,
                ],
                action: [0.7, 0.2],
                lanes: [0.033460235711826, 0.049495734676616],
                terms: [0.0, 0.0, 0.0],
            },
            Agent {
                state: [
                    0.9334380723397618,
                    0.17661643498448704,
                    1.8577963267948967,
                    0.5,
                    0.2,
                ],
                action: [0.5, 0.25],
                lanes: [-0.012855905591085787, 0.07759361391332842],
                terms: [-0.12855905591085787, 0.0, 0.0],
            },
        ],
        pairs: &[((0, 1), 0.022756058358755098)],
    },
    Case {
        name: "C8 three cars",
        lane: Lane::Straight,
        agents: &[
            Agent {
                state: [0.0, 0.06, -0.2, 0.5, -0.1],
                action: [0.6, -0.2],
                lanes: [0.03258645217521264, 0.016869579289583436],
                terms: [0.0, 0.0, -0.4780351599274325],
            },
            Agent {
                state: [0.06, -0.06, 0.3, 0.6, 0.1],
                action: [0.7, 0.3],
                lanes: [-0.015128951273816818, 0.047979434494128226],
                terms: [-0.15128951273816818, 0.0, -0.5331961971674612],
            },
            Agent {
                state: [0.5, -0.02, 0.0, -0.15, 0.0],
                action: [-0.25, 0.1],
                lanes: [0.0526258209531314, 0.029603359896305692],
                terms: [0.0, 0.0, -0.5331961971674612],
            },
        ],
        pairs: &[
            ((0, 1), -0.021010438796790785),
            ((0, 2), -0.047803515992743253),
            ((1, 2), -0.05331961971674613),
        ],
    },
];

fn parameters() -> MarginParameters {
    let agents = AgentRows {
        length_m: 0.22,
        width_m: 0.107,
        range_m: f64::INFINITY,
        predictor: None,
    };
    MarginParameters {
        rows: CbfParameters {
            length_m: 0.22,
            rear_axle_m: 0.075,
            wheelbase_m: 0.15,
            circle_radius_m: agents.circle_radius_m(3),
            gain: 0.5,
            step_s: 0.2,
            acceleration_limit_mps2: 5.0,
            steering_rate_limit_radps: std::f64::consts::FRAC_PI_2,
            speed_range_mps: [-0.5, 1.0],
            max_steering_rad: 31f64.to_radians() as f32,
            agents: Some(agents),
            arithmetic: Arithmetic::Numpy1,
            ..CbfParameters::sigmarl(0.2)
        },
        command_step_s: 0.1,
    }
}

#[test]
fn the_margins_and_rewards_are_sigmarls() {
    let p = parameters();
    for case in CASES {
        let (left, right) = case.lane.boundaries();
        let vehicles: Vec<Vehicle<'_>> = case
            .agents
            .iter()
            .map(|a| {
                let s = a.state.map(|v| v as f32);
                Vehicle {
                    state: CbfState {
                        x_m: s[0],
                        y_m: s[1],
                        yaw_rad: s[2],
                        speed_mps: s[3],
                        steering_rad: s[4],
                    },
                    nominal: a.action.map(|v| v as f32),
                    left: &left,
                    right: &right,
                }
            })
            .collect();
        let margins = joint_margins(&p, &vehicles);
        let name = case.name;
        for (k, (agent, m)) in case.agents.iter().zip(&margins).enumerate() {
            let close = |found: f64, expected: f64, what: &str| {
                assert!(
                    (found - expected).abs() < 1e-12,
                    "{name}, agent {k}, {what}: {found} vs SigmaRL's {expected}"
                );
            };
            close(m.left, agent.lanes[0], "left");
            close(m.right, agent.lanes[1], "right");
            let worst_pair = case
                .pairs
                .iter()
                .filter(|((i, j), _)| *i == k || *j == k)
                .map(|(_, g)| *g)
                .fold(0.0, f64::min);
            close(m.agents, worst_pair, "between agents");
            let expected = agent.terms.iter().sum::<f64>() / 3.0;
            close(m.reward(0.1), expected, "reward");
        }
    }
}
