//! What a front end of cpmx does with a spec, shared by the command line (`src/`) and the
//! Python package (`python/`): load and check it with every diagnostic the commands show
//! (`load`), and run its matrix into a run folder (`run`). Nothing here prints: outcomes and
//! problems are returned as values for the front end to render in its own way (text on a
//! terminal, exceptions and objects in Python).

mod load;
mod run;

pub use load::{LoadError, load, load_from};
pub use run::{MatrixRun, ONLY_AXES, Only, RunError, RunRequest, parse_only, run_matrix, selected_plans};
