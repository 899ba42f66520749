//! The rectangular footprint of a vehicle, with SigmaRL's corner order.

use crate::VehicleParams;

/// The four corners of a footprint: front-left, front-right, rear-right, rear-left.
pub type Footprint = [[f64; 2]; 4];

/// Corners of a `length_m` x `width_m` rectangle centred at `(x_m, y_m)` with heading `yaw_rad`,
/// in SigmaRL's order: local offsets `(+L/2, +W/2)`, `(+L/2, -W/2)`, `(-L/2, -W/2)`, `(-L/2, +W/2)`.
pub fn footprint_corners(params: &VehicleParams, x_m: f64, y_m: f64, yaw_rad: f64) -> Footprint {
    let (half_l, half_w) = (params.length_m / 2.0, params.width_m / 2.0);
    let (sin, cos) = yaw_rad.sin_cos();
    let local = [
        [half_l, half_w],
        [half_l, -half_w],
        [-half_l, -half_w],
        [-half_l, half_w],
    ];
    local.map(|[lx, ly]| [x_m + lx * cos - ly * sin, y_m + lx * sin + ly * cos])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corners_of_an_axis_aligned_car_are_in_sigmarl_order() {
        let c = footprint_corners(&VehicleParams::MU_CAR, 1.0, 2.0, 0.0);
        assert_eq!(c[0], [1.11, 2.0535]);
        assert_eq!(c[2], [0.89, 1.9465]);
    }

    #[test]
    fn rotating_by_a_quarter_turn_moves_the_front_up() {
        let c = footprint_corners(&VehicleParams::MU_CAR, 0.0, 0.0, std::f64::consts::FRAC_PI_2);
        assert!((c[0][1] - 0.11).abs() < 1e-12 && (c[0][0] + 0.0535).abs() < 1e-12);
    }
}
