//! `cpmx validate SPEC...`: every problem of every spec, or one line per valid spec.

use std::path::PathBuf;

use super::{Failure, load_checked};
use crate::DataArgs;

pub fn run(specs: &[PathBuf], data: &DataArgs) -> Result<(), Failure> {
    let mut failed = false;
    for path in specs {
        match load_checked(path, data) {
            Ok(checked) => println!("ok: {}: {} runs", path.display(), checked.plan().len()),
            Err(_) => failed = true,
        }
    }
    if failed {
        Err(Failure::InvalidInput)
    } else {
        Ok(())
    }
}
