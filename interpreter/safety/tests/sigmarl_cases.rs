//! The filter against SigmaRL's own: each case's state, nominal action and lane went through
//! SigmaRL's `CBFQP.solve_decentralized_cbf_qp` (bassamlab/SigmaRL tag 1.4.0, `cbf_qp.py` and
//! `pseudo_distance.py` unchanged, NumPy 2.0.2 and 2.4.6 alike) with its QP solved by Clarabel at
//! 1e-10 instead of SCS at 1e-5 (whose own error reaches 5e-4 in the inputs); the actions,
//! fallbacks and active rows below are what it wrote. Straight lanes of half-width 0.15 m
//! (points every 0.05 m for x in −2..2) and a lane on a circle of radius 1 m (boundaries at
//! 0.85 and 1.15 m, every 0.05 rad from −1.5 rad), as `float32` polylines.

mod support;

use cpmx_safety::{CbfParameters, CbfState, Fallback, filter};
use support::Lane;

struct Case {
    name: &'static str,
    lane: Lane,
    circles: usize,
    state: [f64; 5],
    nominal: [f64; 2],
    action: [f64; 2],
    fallback: Option<Fallback>,
    active: &'static [usize],
}

const CASES: &[Case] = &[
    Case {
        name: "A",
        lane: Lane::Straight,
        circles: 3,
        state: [
            0.0,
            0.07999999821186066,
            0.20000000298023224,
            0.800000011920929,
            0.10000000149011612,
        ],
        nominal: [1.0, 0.30000001192092896],
        action: [0.8014386296272278, -0.7853981852531433],
        fallback: None,
        active: &[0, 5],
    },
    Case {
        name: "C",
        lane: Lane::Straight,
        circles: 3,
        state: [0.0, 0.10000000149011612, 0.5, 1.0, 0.30000001192092896],
        nominal: [1.0, 0.6000000238418579],
        action: [-0.5, -0.7853981852531433],
        fallback: None,
        active: &[0, 5],
    },
    Case {
        name: "E",
        lane: Lane::Straight,
        circles: 3,
        state: [0.0, 0.03999999910593033, 1.570796251296997, 1.0, 0.0],
        nominal: [1.0, 0.0],
        action: [-0.5, -3.724507905644714e-06],
        fallback: None,
        active: &[4],
    },
    Case {
        name: "F",
        lane: Lane::Straight,
        circles: 3,
        state: [0.0, 0.05000000074505806, 1.570796251296997, 1.0, 0.0],
        nominal: [1.0, 0.0],
        action: [1.0, 0.0],
        fallback: Some(Fallback::Infeasible),
        active: &[],
    },
    Case {
        name: "A_n5",
        lane: Lane::Straight,
        circles: 5,
        state: [
            0.0,
            0.07999999821186066,
            0.20000000298023224,
            0.800000011920929,
            0.10000000149011612,
        ],
        nominal: [1.0, 0.30000001192092896],
        action: [0.2991710901260376, -0.7853981852531433],
        fallback: None,
        active: &[0, 9],
    },
    Case {
        name: "END",
        lane: Lane::Straight,
        circles: 3,
        state: [1.9850000143051147, 0.10000000149011612, 0.0, 0.5, 0.0],
        nominal: [1.0, 0.0],
        action: [1.0, 0.0],
        fallback: Some(Fallback::NotFinite),
        active: &[],
    },
    Case {
        name: "R01",
        lane: Lane::Arc,
        circles: 3,
        state: [
            0.9484730362892151,
            -0.5210251212120056,
            0.6213857531547546,
            0.4720703065395355,
            -0.16168099641799927,
        ],
        nominal: [0.9006308913230896, -0.45976728200912476],
        action: [0.12293028086423874, 0.7853981852531433],
        fallback: None,
        active: &[1],
    },
    Case {
        name: "R05",
        lane: Lane::Arc,
        circles: 5,
        state: [
            1.0892027616500854,
            0.0036846608854830265,
            1.1148548126220703,
            0.6464259624481201,
            -0.1304120123386383,
        ],
        nominal: [-0.032923899590969086, 0.6223819255828857],
        action: [-0.24653969705104828, 0.7853981852531433],
        fallback: None,
        active: &[1],
    },
    Case {
        name: "R08",
        lane: Lane::Straight,
        circles: 3,
        state: [
            0.1586875170469284,
            -0.1578914076089859,
            -0.04134311527013779,
            0.3193938434123993,
            0.3513680696487427,
        ],
        nominal: [-0.08092891424894333, -0.6746736168861389],
        action: [-0.08092891424894333, -0.6746736168861389],
        fallback: Some(Fallback::Infeasible),
        active: &[],
    },
    Case {
        name: "R10",
        lane: Lane::Straight,
        circles: 3,
        state: [
            -0.5881956815719604,
            -0.1574409157037735,
            -0.5045261383056641,
            0.6506766676902771,
            0.30746951699256897,
        ],
        nominal: [-0.32543912529945374, -0.46256309747695923],
        action: [-0.5, -0.12889166176319122],
        fallback: None,
        active: &[3, 5],
    },
    Case {
        name: "R12",
        lane: Lane::Straight,
        circles: 5,
        state: [
            -0.2391669750213623,
            0.0938674584031105,
            -0.5175096392631531,
            0.28463128209114075,
            0.10535594075918198,
        ],
        nominal: [0.5964308381080627, -0.04019617289304733],
        action: [0.5964308381080627, -0.040196169167757034],
        fallback: None,
        active: &[],
    },
];

#[test]
fn the_filter_gives_sigmarls_actions_fallbacks_and_active_rows() {
    for case in CASES {
        let (left, right) = case.lane.boundaries();
        let parameters = CbfParameters {
            circles: case.circles,
            ..CbfParameters::sigmarl(0.05)
        };
        let s = case.state.map(|v| v as f32);
        let state = CbfState {
            x_m: s[0],
            y_m: s[1],
            yaw_rad: s[2],
            speed_mps: s[3],
            steering_rad: s[4],
        };
        let out = filter(&parameters, state, case.nominal.map(|v| v as f32), &left, &right);
        let name = case.name;
        assert_eq!(out.fallback, case.fallback, "{name}");
        assert_eq!(out.active, case.active, "{name}");
        for k in 0..2 {
            let difference = (f64::from(out.action[k]) - case.action[k]).abs();
            assert!(
                difference <= 1e-6,
                "{name}: action {:?} against SigmaRL's {:?}",
                out.action,
                case.action
            );
        }
        assert_eq!(out.rows.len(), 2 * case.circles, "{name}");
    }
}
