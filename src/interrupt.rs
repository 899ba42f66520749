//! Ctrl-C (SIGINT), SIGTERM and SIGHUP: the first one asks the command to stop after the step
//! under way (a run of `cpmx run`, an iteration of `cpmx train`), so that what it keeps is whole
//! and it can say how to resume; a second one ends the process at once, which leaves the
//! folder consistent too (every file is written under a temporary name and renamed), only
//! without the message.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};

/// The exit code of an interrupted command (128 + SIGINT, as shells report it).
pub const EXIT_CODE: u8 = 130;

static FLAG: OnceLock<Arc<AtomicBool>> = OnceLock::new();

/// The flag set by the first interrupt, with the handler installed on first use. Without a
/// handler (the platform refused one) the flag is never set and signals end the process as
/// they would anyway.
pub fn flag() -> Arc<AtomicBool> {
    FLAG.get_or_init(|| {
        let flag = Arc::new(AtomicBool::new(false));
        let seen = flag.clone();
        let installed = ctrlc::set_handler(move || {
            if seen.swap(true, Ordering::SeqCst) {
                eprintln!("\ninterrupted again: stopping now");
                std::process::exit(i32::from(EXIT_CODE));
            }
            eprintln!("\ninterrupt: finishing the step under way (Ctrl-C again stops at once)");
        });
        if let Err(e) = installed {
            eprintln!("note: Ctrl-C will not stop cleanly: {e}");
        }
        flag
    })
    .clone()
}

/// Whether an interrupt has been received.
pub fn requested() -> bool {
    FLAG.get().is_some_and(|f| f.load(Ordering::SeqCst))
}
