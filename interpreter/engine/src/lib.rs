//! Executes cpmx runs: the engines (sim today), the checks that need the interpreter, and the
//! run folder.

mod checks;

pub use checks::BuildChecks;
