//! Every function within 1 ulp of a 128-bit reference on a sample of each case's arguments
//! (the documented measurement, `examples/accuracy.rs`, takes 10^7 per case).

mod support;

use support::reference::{CASES, Reference, stream};

#[test]
fn every_case_is_within_one_ulp_on_a_sample() {
    let mut reference = Reference::new();
    for (index, case) in CASES.iter().enumerate() {
        let mut rng = stream(1_000 + index as u64);
        let mut worst = (0.0f64, 0.0, 0.0);
        for _ in 0..2_000 {
            let (x, y) = case.arguments(&mut rng);
            for error in reference.errors(case, x, y) {
                if error > worst.0 {
                    worst = (error, x, y);
                }
            }
        }
        assert!(
            worst.0 < 1.0,
            "{}: {:.3} ulp at x = {:e}, y = {:e}",
            case.name(),
            worst.0,
            worst.1,
            worst.2
        );
    }
}

#[test]
fn the_reference_measures_what_it_should() {
    // A wrong last bit is one ulp; a right answer none.
    let mut reference = Reference::new();
    let case = support::reference::Case::Exp { lo: 0.0, hi: 0.0 };
    assert_eq!(reference.errors(&case, 0.0, 0.0), vec![0.0]);
    let exact = astro_float_num::BigFloat::from_f64(1.5, 256);
    let next = f64::from_bits(1.5f64.to_bits() + 1);
    assert_eq!(support::reference::ulp_error(next, &exact), 1.0);
    assert_eq!(support::reference::ulp_error(1.5, &exact), 0.0);
}
