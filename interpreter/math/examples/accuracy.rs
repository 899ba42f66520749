//! The functions' accuracy against a 128-bit reference (astro-float), on 1.2·10^6 arguments per case (10.8·10^6 in all)
//! by default (docs/performance.md quotes the table it prints):
//!
//!     cargo run --release -p cpmx-math --example accuracy [-- ARGUMENTS_PER_CASE [FUNCTION]]
//!
//! FUNCTION (`sin_cos`, `exp`, `pow`, `atan2`, `hypot`) measures that function's cases alone.
//!
//! Each case's arguments are one seeded stream, split over rayon's threads in fixed chunks, so
//! the table is the same on any thread count.

#[path = "../tests/support/reference.rs"]
mod reference;

use rayon::prelude::*;
use reference::{CASES, Reference, stream};

const CHUNK: usize = 10_000;

fn main() {
    let per_case: usize = match std::env::args().nth(1).map(|a| a.parse()) {
        None => 1_200_000,
        Some(Ok(n)) if n > 0 => n,
        Some(_) => {
            eprintln!("accuracy: ARGUMENTS_PER_CASE must be a positive integer");
            std::process::exit(2);
        }
    };
    let only = std::env::args().nth(2);
    if let Some(name) = &only
        && !CASES
            .iter()
            .any(|case| case.name().starts_with(&format!("{name},")))
    {
        eprintln!("accuracy: no case measures `{name}` (sin_cos, exp, pow, atan2, hypot)");
        std::process::exit(2);
    }
    println!("| case | arguments | max error [ulp] | at x | share above 0.5 ulp |");
    println!("| :-- | --: | --: | --: | --: |");
    for (index, case) in CASES.iter().enumerate() {
        if only
            .as_ref()
            .is_some_and(|name| !case.name().starts_with(&format!("{name},")))
        {
            continue;
        }
        let chunks = per_case.div_ceil(CHUNK);
        let (worst, at, above, count) = (0..chunks)
            .into_par_iter()
            .map_init(Reference::new, |reference, chunk| {
                let mut rng = stream((index as u64) << 32 | chunk as u64);
                let n = CHUNK.min(per_case - chunk * CHUNK);
                let (mut worst, mut at, mut above, mut count) = (0.0f64, (0.0, 0.0), 0usize, 0usize);
                for _ in 0..n {
                    let (x, y) = case.arguments(&mut rng);
                    for error in reference.errors(case, x, y) {
                        count += 1;
                        if error > 0.5 {
                            above += 1;
                        }
                        if error > worst {
                            (worst, at) = (error, (x, y));
                        }
                    }
                }
                (worst, at, above, count)
            })
            .reduce(
                || (0.0, (0.0, 0.0), 0, 0),
                |a, b| {
                    let (worst, at) = if b.0 > a.0 { (b.0, b.1) } else { (a.0, a.1) };
                    (worst, at, a.2 + b.2, a.3 + b.3)
                },
            );
        println!(
            "| {} | {count} | {worst:.3} | {:e}{} | {:.2e} |",
            case.name(),
            at.0,
            if at.1 == 0.0 {
                String::new()
            } else {
                format!(", y {:e}", at.1)
            },
            above as f64 / count as f64
        );
    }
}
